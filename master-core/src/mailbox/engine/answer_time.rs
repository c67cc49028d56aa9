//! How long a slave takes to answer, learned from its last answers, so that the first read
//! of SM1 after the eager ones goes when the answer is due instead of after a fixed pause.
//!
//! A slave's application answers after its own delay (ETG.1000.4, spec-notes
//! §mbx.handshake), often about the same from one request to the next. What is learned per
//! answer is when, after the write's frame left, the frame of the read that found the answer
//! left: the read found it on its way out, so the answer was there by then, and the time
//! the frame took to come back (and its caller to be woken) is not counted. The least of
//! the last [`KEPT`] such times is taken: one slow request (a long SDO, an FoE block) does
//! not make the next fast ones wait, and a slave that answers at once (to the read in the
//! write's own frame) keeps the learned time below [`PLAN_FROM`], where nothing is planned.
//!
//! Why the time the read left, not the time it came back: a planned read that finds the
//! answer at once says only that the answer was there when it passed the slave, not how
//! long before. Timed from its return, each such read would plan the next one later by
//! its own round trip, and the plan had to be moved back by an estimate of that round
//! trip (the writes'); wherever the estimate fell short of the reads' own, the plan crept
//! later with nothing to bring it back. Slaves answering after 100 µs and 1 ms were read
//! 136-309 µs past their answers so (`perf_veth`, 2026-12-06 and 2026-12-07; the test
//! `the_plan_does_not_creep_later_when_reads_take_longer_than_writes` below). Timed from
//! when it left, a read that finds the answer at once plans the next one no later, and the
//! least of eight such times moves earlier until a planned read finds nothing; the eager
//! reads then find the answer, and their times hold the plan there.

use std::time::Duration;

use super::exchange::FIRST_PAUSE;

/// Answer times kept per slave.
pub(crate) const KEPT: usize = 8;
/// Learned times shorter than this plan nothing: the eager reads cover them.
pub(crate) const PLAN_FROM: Duration = FIRST_PAUSE;
/// The most one planned read's lateness counts with: a stall of the machine must not move
/// the planned reads far ahead of the answer.
const MAX_LATE: Duration = Duration::from_micros(200);

/// The last answer times of one slave: from the write's frame to the frame of the read
/// that found the answer.
#[derive(Debug, Clone, Default)]
pub(crate) struct AnswerTimes {
    times: [Duration; KEPT],
    next: usize,
    len: usize,
    /// How late planned reads left lately, after the moment planned for them (a moving
    /// average): the pause's timer, the caller and the bus thread woken, which on an idle
    /// machine take tens of µs.
    late: Duration,
}

impl AnswerTimes {
    /// Notes one answer time.
    pub fn record(&mut self, time: Duration) {
        self.times[self.next] = time;
        self.next = (self.next + 1) % KEPT;
        self.len = (self.len + 1).min(KEPT);
    }

    /// Notes how late a planned read left.
    pub fn left_late(&mut self, late: Duration) {
        self.late = (self.late * 3 + late.min(MAX_LATE)) / 4;
    }

    /// How long after the write's frame the first planned read should be asked for, if
    /// the slave is known to take long enough for one: the least recent answer time less
    /// how late planned reads lately left. Nothing before two answers are known.
    pub fn planned(&self) -> Option<Duration> {
        if self.len < 2 {
            return None;
        }
        let least = self.times[..self.len].iter().min().copied()?;
        (least >= PLAN_FROM).then(|| least.saturating_sub(self.late))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    #[test]
    fn a_slow_slave_is_read_at_its_least_recent_answer_time() {
        let mut times = AnswerTimes::default();
        assert_eq!(times.planned(), None);
        times.record(us(130));
        assert_eq!(times.planned(), None, "one answer is no pattern");
        times.record(us(112));
        times.record(us(190));
        assert_eq!(times.planned(), Some(us(112)));
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
        assert_eq!(times.planned(), Some(us(400)));
    }

    #[test]
    fn reads_that_leave_late_are_planned_earlier_by_as_much() {
        let mut times = AnswerTimes::default();
        times.record(us(300));
        times.record(us(320));
        for _ in 0..20 {
            times.left_late(us(40));
        }
        let planned = times.planned().unwrap();
        assert!(planned <= us(262) && planned >= us(260), "{planned:?}");
        // A stall counts only up to its bound.
        for _ in 0..20 {
            times.left_late(Duration::from_secs(1));
        }
        assert!(times.planned().unwrap() >= us(300) - MAX_LATE);
    }

    #[test]
    fn one_slow_answer_does_not_delay_the_next_reads() {
        let mut times = AnswerTimes::default();
        for t in [120, 110, 5_000, 115] {
            times.record(us(t));
        }
        assert_eq!(times.planned(), Some(us(110)));
    }

    /// A deterministic sequence of round trips in `lo..=hi` µs (a linear congruential
    /// generator: the same every run).
    struct Trips {
        state: u64,
        lo: u64,
        hi: u64,
    }

    impl Trips {
        fn new(state: u64, lo: u64, hi: u64) -> Trips {
            Trips { state, lo, hi }
        }

        fn next(&mut self) -> Duration {
            self.state = self.state.wrapping_mul(6364136223846793005).wrapping_add(1);
            us(self.lo + (self.state >> 33) % (self.hi - self.lo + 1))
        }
    }

    /// What one exchange came to: when the answer was in hand after it was ready, and how
    /// many reads it took (the one in the write's frame included).
    struct Exchange {
        late: Duration,
        reads: u32,
    }

    /// One exchange as the engine runs it, in a model: the slave's answer is ready `ready`
    /// after the write's frame left; a read reaches the slave half its round trip after
    /// its frame left, and is in its caller's hands a whole round trip after; the planned
    /// read leaves `wake` after the moment planned for it; the reads behind one that found
    /// nothing leave as it comes back. The write's frame (with the first read) takes a
    /// round trip from `writes`, every later read one from `reads`.
    fn exchange(
        times: &mut AnswerTimes,
        ready: Duration,
        wake: Duration,
        writes: &mut Trips,
        trips: &mut Trips,
    ) -> Exchange {
        // The read in the write's own frame.
        let mut left = Duration::ZERO;
        let mut trip = writes.next();
        let mut reads = 1;
        if trip / 2 < ready {
            // It found nothing: the planned read goes, if there is a plan and its moment
            // comes after this read is back, else the next read as this one is back.
            left = match times.planned() {
                Some(planned) if planned > trip => {
                    times.left_late(wake);
                    planned + wake
                }
                _ => trip,
            };
            trip = trips.next();
            reads += 1;
            while left + trip / 2 < ready {
                left += trip;
                trip = trips.next();
                reads += 1;
            }
        }
        times.record(left);
        Exchange {
            late: left + trip - ready,
            reads,
        }
    }

    /// `n` exchanges from nothing learned, each planned read leaving a time from `wakes`
    /// late (see [`exchange`]).
    fn run(
        n: usize,
        ready: Duration,
        mut wakes: Trips,
        mut writes: Trips,
        mut trips: Trips,
    ) -> Vec<Exchange> {
        let mut times = AnswerTimes::default();
        (0..n)
            .map(|_| exchange(&mut times, ready, wakes.next(), &mut writes, &mut trips))
            .collect()
    }

    #[test]
    fn the_plan_does_not_creep_later_when_reads_take_longer_than_writes() {
        // Writes back in 30-60 µs, the reads after them in 40-120 µs (the bus thread asleep
        // again, as on a loaded machine), planned reads leaving 20-60 µs late. Timed from
        // their return and led by the writes' round trip, the answers were in hand up to
        // 312 µs (100 µs slave) and 341 µs (1 ms) after they were ready from the 200th
        // exchange on, at 2.0 reads each (this model, with the old rule: the slaves of
        // `perf_veth` were read 136-309 µs past their answers at 2.00-2.11 frames). Timed
        // from when they left, within two read round trips, at three reads at most on
        // average.
        for ready in [us(100), us(1_000)] {
            let runs = run(
                300,
                ready,
                Trips::new(11, 20, 60),
                Trips::new(5, 30, 60),
                Trips::new(7, 40, 120),
            );
            let tail = &runs[200..];
            let worst = tail.iter().map(|r| r.late).max().unwrap();
            let reads = tail.iter().map(|r| r.reads).sum::<u32>() as f64 / tail.len() as f64;
            assert!(
                worst <= us(240),
                "{ready:?}: in hand {worst:?} after the answer"
            );
            assert!(reads <= 3.0, "{ready:?}: {reads} reads per answer");
        }
    }

    #[test]
    fn with_steady_round_trips_the_planned_read_finds_the_answer_on_its_way_out() {
        // Nothing varies: the plan settles on the first read that finds the answer, and
        // from then on every answer takes the write's frame and one planned read.
        let steady = || Trips::new(1, 70, 70);
        let runs = run(50, us(100), Trips::new(1, 0, 0), steady(), steady());
        let last = runs.last().unwrap();
        assert_eq!(last.reads, 2);
        assert!(last.late <= us(70), "{:?}", last.late);
        assert!(
            runs[10..]
                .iter()
                .all(|r| r.reads == 2 && r.late == last.late)
        );
    }
}
