//! How long a slave takes to answer, learned from its last answers, so that the first read
//! of SM1 after the eager ones goes when the answer is due instead of after a fixed pause.
//!
//! A slave's application answers after its own delay (ETG.1000.4, spec-notes
//! §mbx.handshake), often about the same from one request to the next. The least of the
//! last [`KEPT`] answer times is taken: one slow request (a long SDO, an FoE block) does not
//! make the next fast ones wait, and a slave that answers at once (in the write's own frame)
//! keeps the learned time below [`PLAN_FROM`], where nothing is planned.

use std::time::Duration;

use super::exchange::FIRST_PAUSE;

/// Answer times kept per slave.
pub(crate) const KEPT: usize = 8;
/// Learned times shorter than this plan nothing: the eager reads cover them.
pub(crate) const PLAN_FROM: Duration = FIRST_PAUSE;
/// How long before the learned time the planned read is asked for while no write's round
/// trip is known yet, besides how late the pauses lately ended. Once one is, the lead is
/// the writes' recent round trip, at least [`MIN_LEAD`].
///
/// The lead must not be shorter than a read's own round trip. A planned read that finds
/// the answer at once records, as the answer time, the moment it came back: its round trip
/// later than it was asked for. Were the lead shorter, each such read would plan the next
/// one later by the difference, with nothing to stop it: a lead capped at 30 µs let
/// slaves answering after 100 µs and 1 ms be read 136-309 µs past their answers on a
/// loaded machine, where round trips took longer (`perf_veth`, 2026-12-06; the test
/// `the_plan_does_not_creep_later_when_round_trips_outlast_the_old_cap` below).
pub(crate) const LEAD: Duration = Duration::from_micros(30);
/// The least lead, on a link whose round trips are shorter (see [`LEAD`]).
pub(crate) const MIN_LEAD: Duration = Duration::from_micros(10);
/// The longest round trip a write counts with: one stall of the machine moves the lead by
/// a quarter of this at most (a few empty reads, until the next writes bring it back).
/// Round trips longer than this on average would let the plan creep again (see [`LEAD`]).
const MAX_TRIP: Duration = Duration::from_micros(200);
/// The most a pause's lateness adds to the lead: a stall of the machine must not move the
/// planned reads far ahead of the answer.
const MAX_LATE: Duration = Duration::from_micros(200);

/// The last answer times of one slave: from the write of a request to its answer in hand.
#[derive(Debug, Clone, Default)]
pub(crate) struct AnswerTimes {
    times: [Duration; KEPT],
    next: usize,
    len: usize,
    /// How late the planned pauses ended lately (a moving average): the wake-ups of the
    /// timer's thread and of the caller, which on an idle machine take tens of µs.
    late: Duration,
    /// The writes' round trips lately (a moving average; `None` before the first): one
    /// empty read costs this much, so the planned read goes about that early.
    trip: Option<Duration>,
}

impl AnswerTimes {
    /// Notes one answer time.
    pub fn record(&mut self, time: Duration) {
        self.times[self.next] = time;
        self.next = (self.next + 1) % KEPT;
        self.len = (self.len + 1).min(KEPT);
    }

    /// Notes the round trip of a write (its frame out and back, and its caller woken).
    pub fn wrote_in(&mut self, trip: Duration) {
        let trip = trip.min(MAX_TRIP);
        self.trip = Some(self.trip.map_or(trip, |t| (t * 3 + trip) / 4));
    }

    /// Notes how late a planned pause ended.
    pub fn woke_late(&mut self, late: Duration) {
        self.late = (self.late * 3 + late.min(MAX_LATE)) / 4;
    }

    /// How long after the write the first planned read should go, if the slave is known
    /// to take long enough for one: the least recent answer time less the lead (the
    /// writes' round trip, at least [`MIN_LEAD`]; [`LEAD`] before any is known) and less
    /// how late the pauses lately ended. Nothing before two answers are known.
    pub fn planned(&self) -> Option<Duration> {
        if self.len < 2 {
            return None;
        }
        let least = self.times[..self.len].iter().min().copied()?;
        let lead = self.trip.map_or(LEAD, |t| t.max(MIN_LEAD));
        (least >= PLAN_FROM).then(|| least.saturating_sub(lead + self.late))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    #[test]
    fn a_slow_slave_is_read_shortly_before_its_least_recent_answer_time() {
        let mut times = AnswerTimes::default();
        assert_eq!(times.planned(), None);
        times.record(us(130));
        assert_eq!(times.planned(), None, "one answer is no pattern");
        times.record(us(112));
        times.record(us(190));
        assert_eq!(times.planned(), Some(us(112) - LEAD));
    }

    #[test]
    fn a_fast_answer_among_the_kept_ones_plans_nothing() {
        let mut times = AnswerTimes::default();
        for t in [400, 420, 20, 410] {
            times.record(us(t));
        }
        assert_eq!(times.planned(), None);
        // Once the fast one is KEPT answers old, the slow pattern counts again.
        for _ in 0..KEPT - 1 {
            times.record(us(400));
        }
        assert_eq!(times.planned(), Some(us(400) - LEAD));
    }

    #[test]
    fn pauses_that_end_late_plan_the_read_earlier_by_as_much() {
        let mut times = AnswerTimes::default();
        times.record(us(300));
        times.record(us(320));
        for _ in 0..20 {
            times.woke_late(us(40));
        }
        let planned = times.planned().unwrap();
        assert!(
            planned <= us(300) - LEAD - us(38) && planned >= us(300) - LEAD - us(40),
            "{planned:?}"
        );
        // A stall counts only up to its bound.
        for _ in 0..20 {
            times.woke_late(Duration::from_secs(1));
        }
        assert!(times.planned().unwrap() >= us(300) - LEAD - MAX_LATE);
    }

    #[test]
    fn the_lead_is_the_writes_round_trip_within_its_bounds() {
        let mut times = AnswerTimes::default();
        times.record(us(200));
        times.record(us(210));
        assert_eq!(
            times.planned(),
            Some(us(200) - LEAD),
            "no round trip known yet"
        );
        for _ in 0..20 {
            times.wrote_in(us(14));
        }
        let planned = times.planned().unwrap();
        assert!(
            planned >= us(200) - us(15) && planned <= us(200) - us(14),
            "{planned:?}"
        );
        // A fast link leads by MIN_LEAD still; a stall counts up to MAX_TRIP.
        for _ in 0..20 {
            times.wrote_in(us(2));
        }
        assert!(times.planned().unwrap() <= us(200) - MIN_LEAD);
        assert!(times.planned().unwrap() >= us(200) - MIN_LEAD - us(1));
        let mut times = AnswerTimes::default();
        times.record(us(5_000));
        times.record(us(5_100));
        for _ in 0..40 {
            times.wrote_in(Duration::from_secs(1));
        }
        let planned = times.planned().unwrap();
        assert!(
            planned >= us(5_000) - MAX_TRIP && planned <= us(5_000) - MAX_TRIP + us(1),
            "{planned:?}"
        );
    }

    /// One exchange as the engine runs it, in a model with fixed times: the slave's answer
    /// is ready `ready` after the write; a read reaches the slave `trip / 2` after it is
    /// asked for and is back in its caller's hands after `trip`; the reads behind a read
    /// that found nothing follow every `trip / 2`. Returns when the answer was in hand.
    fn exchange(times: &mut AnswerTimes, ready: Duration, trip: Duration) -> Duration {
        times.wrote_in(trip);
        let asked = times.planned().unwrap_or(Duration::ZERO);
        let mut passes = asked + trip / 2;
        while passes < ready {
            passes += trip / 2;
        }
        let in_hand = passes + trip / 2;
        times.record(in_hand);
        in_hand
    }

    #[test]
    fn the_plan_does_not_creep_later_when_round_trips_outlast_the_old_cap() {
        // Round trips of 70 µs, as a loaded machine gives (or a link 40 µs long): every
        // planned read that finds the answer at once records its own round trip on top of
        // the time it was asked for. With the lead capped at 30 µs, the plan moved 40 µs
        // later each time the older answers had left the eight kept, and the 100th read
        // came back 560 µs after the answer was ready; with the lead the round trip, every
        // read from the third on comes back 40 µs after it.
        let (ready, trip) = (us(100), us(70));
        let mut times = AnswerTimes::default();
        let late: Vec<Duration> = (0..100)
            .map(|_| exchange(&mut times, ready, trip) - ready)
            .collect();
        let last = *late.last().unwrap();
        assert!(last <= trip, "in hand {last:?} after the answer: {late:?}");
        assert!(late[10..].iter().all(|&l| l == last), "{late:?}");
    }

    #[test]
    fn one_slow_answer_does_not_delay_the_next_reads() {
        let mut times = AnswerTimes::default();
        for t in [120, 110, 5_000, 115] {
            times.record(us(t));
        }
        assert_eq!(times.planned(), Some(us(110) - LEAD));
    }
}
