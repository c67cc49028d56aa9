//! Cable redundancy as the APIs show it: the ring's state in `GetMaster` /
//! `GET /api/v1/master`, and the `ring_broken` / `ring_closed` events.
//!
//! The ring link on the bus thread knows the ring from every frame (master-core's
//! `bus::redundancy`, spec-notes §redundancy) and bumps a generation counter at every change
//! of state or break position. [`RingEvents`] polls that counter (one atomic load) every
//! [`RING_POLL`], so an event is at most that late, and turns each change into an event:
//! `ring_broken` whenever the ring is found broken or its break moves, `ring_closed` when
//! it closes again after a break, each with the ring's state ([`RedundancyView`]). The
//! first closing at start is no news and has no event.

use std::time::Duration;

use master_core::bus::redundancy::{RingState, RingStatus, RingWatch};

use super::Core;
use super::view::{EventView, RedundancyView};

/// How often the ring's generation is looked at: the most an event is late.
pub const RING_POLL: Duration = Duration::from_millis(2);

impl Core {
    /// The ring's state now; `off` on a single port.
    pub fn redundancy(&self) -> RedundancyView {
        match self.master().bus().ring() {
            Some(watch) => RedundancyView::of(&watch.status()),
            None => RedundancyView::off(),
        }
    }
}

/// Turns the ring's changes into events; see the module documentation.
#[derive(Debug)]
pub struct RingEvents {
    watch: RingWatch,
    generation: u64,
    last: RingState,
}

impl RingEvents {
    /// Starts from the ring as it is now: a break already there is news (nobody has been
    /// told), the ring closed at start is not.
    pub fn new(watch: RingWatch) -> RingEvents {
        RingEvents {
            watch,
            // Not a generation the counter has had since it started at 0: the first look
            // always reads the status.
            generation: u64::MAX,
            last: RingState::Unknown,
        }
    }

    /// One look: the event to publish, if the ring changed since the last look.
    pub fn look(&mut self) -> Option<EventView> {
        let generation = self.watch.generation();
        if generation == self.generation {
            return None;
        }
        self.generation = generation;
        self.step(&self.watch.status())
    }

    fn step(&mut self, status: &RingStatus) -> Option<EventView> {
        let before = std::mem::replace(&mut self.last, status.state);
        match status.state {
            RingState::Broken => Some(broken(status)),
            RingState::Closed if before == RingState::Broken => Some(EventView {
                ring: Some(RedundancyView::of(status)),
                ..EventView::note(
                    "ring_closed",
                    format!(
                        "ring closed again: all {} slaves on both ports",
                        status.ring_slaves
                    ),
                )
            }),
            RingState::Closed | RingState::Unknown => None,
        }
    }
}

/// `ring broken after 3 slaves (positions 0-2 on the primary port, 3-7 on the backup
/// port)`: positions as the slaves have them in the closed ring, and the unreachable ones
/// after a `;`.
fn broken(status: &RingStatus) -> EventView {
    let after = status.break_after.unwrap_or(status.primary_side);
    let range = |first: u16, count: u16| match count {
        0 => None,
        1 => Some(first.to_string()),
        n => Some(format!("{first}-{}", first + (n - 1))),
    };
    let worded = |range: Option<String>| match range {
        None => "none".to_owned(),
        Some(r) if r.contains('-') => format!("positions {r}"),
        Some(r) => format!("position {r}"),
    };
    let backup_first = status.ring_slaves.saturating_sub(status.backup_side);
    let primary = range(0, status.primary_side);
    // "positions" once, as one would say it: "positions 0-2 on the primary port, 3-7 on
    // the backup port".
    let backup = match (&primary, range(backup_first, status.backup_side)) {
        (Some(_), Some(r)) => r,
        (None, r) => worded(r),
        (Some(_), None) => "none".to_owned(),
    };
    // "after 3 slaves", not "after slave 3": positions count from 0.
    let place = match after {
        0 => "at the master's primary cable".to_owned(),
        1 => "after 1 slave".to_owned(),
        n => format!("after {n} slaves"),
    };
    let mut text = format!(
        "ring broken {place} ({} on the primary port, {backup} on the backup port)",
        worded(primary)
    );
    if status.unreachable > 0 {
        text.push_str(&format!(
            "; {} unreachable ({})",
            status.unreachable,
            worded(range(status.primary_side, status.unreachable))
        ));
    }
    EventView {
        ring: Some(RedundancyView::of(status)),
        ..EventView::note("ring_broken", text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(state: RingState, primary: u16, backup: u16) -> RingStatus {
        let broken = state == RingState::Broken;
        RingStatus {
            state,
            primary_side: primary,
            backup_side: backup,
            ring_slaves: 8,
            break_after: broken.then_some(primary),
            unreachable: if broken { 8 - primary - backup } else { 0 },
            breaks: 0,
            heals: 0,
            single_returns: 0,
            incomplete: 0,
        }
    }

    #[test]
    fn a_break_its_move_and_the_heal_are_one_event_each_and_the_start_none() {
        let mut events = RingEvents::new(RingWatch::default());
        assert_eq!(events.step(&status(RingState::Unknown, 0, 0)), None);
        assert_eq!(
            events.step(&status(RingState::Closed, 8, 0)),
            None,
            "closed at start"
        );
        let broken = events
            .step(&status(RingState::Broken, 3, 5))
            .expect("a break");
        assert_eq!(broken.kind, "ring_broken");
        assert_eq!(
            broken.text,
            "ring broken after 3 slaves (positions 0-2 on the primary port, 3-7 on the backup port)"
        );
        let ring = broken.ring.expect("the ring's state");
        assert_eq!(
            (
                ring.state.as_str(),
                ring.break_after,
                ring.primary_side,
                ring.backup_side,
                ring.unreachable
            ),
            ("broken", Some(3), 3, 5, 0)
        );
        let killed = events
            .step(&status(RingState::Broken, 3, 4))
            .expect("moved");
        assert_eq!(
            killed.text,
            "ring broken after 3 slaves (positions 0-2 on the primary port, 4-7 on the backup \
             port); 1 unreachable (position 3)"
        );
        let closed = events
            .step(&status(RingState::Closed, 8, 0))
            .expect("healed");
        assert_eq!(closed.kind, "ring_closed");
        assert_eq!(closed.ring.map(|r| r.state), Some("closed".to_owned()));
    }

    #[test]
    fn a_look_without_a_new_generation_reads_nothing() {
        let mut events = RingEvents::new(RingWatch::default());
        assert_eq!(events.look(), None, "unknown: no event");
        assert_eq!(events.generation, 0);
        assert_eq!(events.look(), None);
    }

    #[test]
    fn a_single_port_shows_off() {
        let off = RedundancyView::off();
        assert_eq!((off.state.as_str(), off.break_after), ("off", None));
        let broken = RedundancyView::of(&status(RingState::Broken, 0, 7));
        assert_eq!(broken.state, "broken");
        assert_eq!(broken.break_after, Some(0), "the primary cable");
        assert_eq!(broken.unreachable, 1);
    }
}
