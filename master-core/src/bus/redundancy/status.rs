//! What the ring link knows about the ring, shared with the rest of the master.
//!
//! The bus thread writes, anyone reads: plain atomics, no lock on the bus thread's side
//! except a `try_lock` of the distributed-clock plan when it was changed.

use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU16, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

/// Whether the ring is whole.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RingState {
    /// No frame has come back yet: nothing is known.
    Unknown,
    /// The ring is closed: a frame sent on the primary port came back on the backup port,
    /// so every cable between the two is whole.
    Closed,
    /// The ring is broken: the frames came back on the ports they were sent from (or one
    /// port's frame was lost). Every slave still reachable from one side is served from it.
    Broken,
}

impl RingState {
    /// The name the APIs use: `unknown`, `closed`, `broken`.
    pub fn name(self) -> &'static str {
        match self {
            RingState::Unknown => "unknown",
            RingState::Closed => "closed",
            RingState::Broken => "broken",
        }
    }

    fn from_u8(value: u8) -> RingState {
        match value {
            1 => RingState::Closed,
            2 => RingState::Broken,
            _ => RingState::Unknown,
        }
    }

    fn to_u8(self) -> u8 {
        match self {
            RingState::Unknown => 0,
            RingState::Closed => 1,
            RingState::Broken => 2,
        }
    }
}

/// A snapshot of the ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RingStatus {
    /// Closed, broken or not known yet.
    pub state: RingState,
    /// Slaves that processed the last frame sent on the primary port.
    pub primary_side: u16,
    /// Slaves that processed the last frame sent on the backup port (0 with the ring
    /// closed: that frame passes every slave through port 1, unprocessed).
    pub backup_side: u16,
    /// Slaves in the ring as last seen closed (0 if it never was).
    pub ring_slaves: u16,
    /// With the ring broken: the break is after this many slaves from the primary port
    /// (between positions `n - 1` and `n`; 0 is the master's primary cable).
    pub break_after: Option<u16>,
    /// With the ring broken: slaves reached from neither port (a powered-off slave, or the
    /// slaves between two breaks). Only known once the ring was seen closed.
    pub unreachable: u16,
    /// Times the ring went from closed to broken.
    pub breaks: u64,
    /// Times the ring went from broken to closed.
    pub heals: u64,
    /// Frames that came back on one port only (a copy lost, not waited for longer than
    /// the ring link's grace).
    pub single_returns: u64,
    /// Frames not handed up because a copy was missing while the slaves on its way were
    /// still there: the bus saw them lost (spec-notes §redundancy).
    pub incomplete: u64,
}

/// One clock of the distributed-clock plan: a slave with DC, by position and station.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RingClock {
    /// Ring position.
    pub position: u16,
    /// Configured station address.
    pub station: u16,
}

/// The ring link's shared state; [`RingWatch`] is the handle on it.
#[derive(Debug, Default)]
pub(crate) struct RingShared {
    state: AtomicU8,
    primary_side: AtomicU16,
    backup_side: AtomicU16,
    ring_slaves: AtomicU16,
    breaks: AtomicU64,
    heals: AtomicU64,
    single_returns: AtomicU64,
    incomplete: AtomicU64,
    /// Bumped at every change of state or break position, so a watcher can tell a change
    /// from a copy of the last snapshot.
    generation: AtomicU64,
    clocks: Mutex<Vec<RingClock>>,
    clocks_changed: AtomicBool,
    /// The master opened the ring on purpose (to time the DC loops): what the copies show
    /// meanwhile is not the cabling.
    held: AtomicBool,
}

/// A handle on what the ring link knows: read by the master's services, written only by
/// the bus thread. Cheap to clone.
#[derive(Debug, Clone, Default)]
pub struct RingWatch {
    pub(crate) shared: Arc<RingShared>,
}

impl RingWatch {
    /// The ring now.
    pub fn status(&self) -> RingStatus {
        let s = &self.shared;
        let state = RingState::from_u8(s.state.load(Ordering::Acquire));
        let primary_side = s.primary_side.load(Ordering::Relaxed);
        let backup_side = s.backup_side.load(Ordering::Relaxed);
        let ring_slaves = s.ring_slaves.load(Ordering::Relaxed);
        let broken = state == RingState::Broken;
        RingStatus {
            state,
            primary_side,
            backup_side: if broken { backup_side } else { 0 },
            ring_slaves,
            break_after: broken.then_some(primary_side),
            unreachable: if broken {
                ring_slaves.saturating_sub(primary_side.saturating_add(backup_side))
            } else {
                0
            },
            breaks: s.breaks.load(Ordering::Relaxed),
            heals: s.heals.load(Ordering::Relaxed),
            single_returns: s.single_returns.load(Ordering::Relaxed),
            incomplete: s.incomplete.load(Ordering::Relaxed),
        }
    }

    /// Changes with every change of state or break position.
    pub fn generation(&self) -> u64 {
        self.shared.generation.load(Ordering::Acquire)
    }

    /// Tells the ring link where the distributed clocks are (the master does, once it has
    /// set them up; the first is the reference clock). With the ring broken, the side
    /// without the reference clock takes its time from its own first clock instead of from
    /// a datagram nobody there answers (spec-notes §redundancy).
    pub fn set_clocks(&self, clocks: &[RingClock]) {
        let mut plan = self
            .shared
            .clocks
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        plan.clear();
        plan.extend_from_slice(clocks);
        self.shared.clocks_changed.store(true, Ordering::Release);
    }

    /// The clock plan, if it changed since the last call (the bus thread's side).
    pub(crate) fn take_clocks(&self, into: &mut Vec<RingClock>) -> bool {
        if !self.shared.clocks_changed.load(Ordering::Acquire) {
            return false;
        }
        // Never wait on the bus thread: a plan being written now is taken next time.
        let Ok(plan) = self.shared.clocks.try_lock() else {
            return false;
        };
        into.clear();
        into.extend_from_slice(&plan);
        self.shared.clocks_changed.store(false, Ordering::Release);
        true
    }

    /// Stops (`true`) or resumes learning the ring from the copies, while the master opens
    /// it on purpose.
    pub(crate) fn set_held(&self, held: bool) {
        self.shared.held.store(held, Ordering::Release);
    }

    /// Records what one pair of copies showed (the bus thread's side).
    pub(crate) fn observe(&self, seen: Observation) {
        let s = &self.shared;
        if s.held.load(Ordering::Acquire) {
            return;
        }
        let before = RingState::from_u8(s.state.load(Ordering::Relaxed));
        let (state, primary, backup) = match seen {
            Observation::Closed { slaves } => {
                s.ring_slaves.store(slaves, Ordering::Relaxed);
                (RingState::Closed, slaves, 0)
            }
            Observation::Broken { primary, backup } => (RingState::Broken, primary, backup),
        };
        let moved = before != state
            || s.primary_side.load(Ordering::Relaxed) != primary
            || s.backup_side.load(Ordering::Relaxed) != backup;
        if !moved {
            return;
        }
        s.primary_side.store(primary, Ordering::Relaxed);
        s.backup_side.store(backup, Ordering::Relaxed);
        match (before, state) {
            (RingState::Closed, RingState::Broken) => {
                s.breaks.fetch_add(1, Ordering::Relaxed);
            }
            (RingState::Broken, RingState::Closed) => {
                s.heals.fetch_add(1, Ordering::Relaxed);
            }
            _ => {}
        }
        s.state.store(state.to_u8(), Ordering::Release);
        s.generation.fetch_add(1, Ordering::Release);
    }

    pub(crate) fn count_single_return(&self) {
        self.shared.single_returns.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn count_incomplete(&self) {
        self.shared.incomplete.fetch_add(1, Ordering::Relaxed);
    }

    /// The state the bus thread builds its next copies for.
    pub(crate) fn plan(&self) -> (RingState, u16, u16, u16) {
        let s = &self.shared;
        (
            RingState::from_u8(s.state.load(Ordering::Acquire)),
            s.primary_side.load(Ordering::Relaxed),
            s.backup_side.load(Ordering::Relaxed),
            s.ring_slaves.load(Ordering::Relaxed),
        )
    }
}

/// What the copies of one frame showed about the ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Observation {
    /// The primary copy came back on the backup port, processed by this many slaves.
    Closed { slaves: u16 },
    /// Each copy came back on its own port (or not at all), processed by this many slaves.
    Broken { primary: u16, backup: u16 },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_break_and_a_heal_are_counted_once_each_and_locate_the_break() {
        let watch = RingWatch::default();
        assert_eq!(watch.status().state, RingState::Unknown);
        watch.observe(Observation::Closed { slaves: 8 });
        watch.observe(Observation::Closed { slaves: 8 });
        let generation = watch.generation();
        watch.observe(Observation::Broken {
            primary: 3,
            backup: 4,
        });
        let status = watch.status();
        assert_eq!(status.state, RingState::Broken);
        assert_eq!(status.break_after, Some(3));
        assert_eq!(status.unreachable, 1, "8 - 3 - 4: one slave lost power");
        assert_eq!((status.breaks, status.heals), (1, 0));
        assert!(watch.generation() > generation);
        watch.observe(Observation::Closed { slaves: 8 });
        let status = watch.status();
        assert_eq!(status.state, RingState::Closed);
        assert_eq!((status.break_after, status.backup_side), (None, 0));
        assert_eq!((status.breaks, status.heals), (1, 1));
    }

    #[test]
    fn the_clock_plan_is_taken_once_per_change() {
        let watch = RingWatch::default();
        let mut plan = Vec::new();
        assert!(!watch.take_clocks(&mut plan));
        let clock = RingClock {
            position: 0,
            station: 0x1001,
        };
        watch.set_clocks(&[clock]);
        assert!(watch.take_clocks(&mut plan));
        assert_eq!(plan, vec![clock]);
        assert!(!watch.take_clocks(&mut plan));
    }
}
