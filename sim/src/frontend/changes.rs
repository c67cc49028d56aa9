//! Changes to the segment asked for from another thread (`--control`), carried out by the
//! frame loop between two frames: it owns the segment, and the only lock it takes for them
//! is this queue's, and only when something is queued.

use std::io::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use sim::segment::Segment;

/// One change to the segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// Power-cycle the slave at this position ([`Segment::power_cycle`]).
    PowerCycle(usize),
    /// Cut this cable ([`Segment::break_cable`]).
    Break(usize),
    /// Take the power from the slave at this position ([`Segment::kill`]).
    Kill(usize),
    /// Reconnect every cable and power every slave ([`Segment::heal`]).
    Heal,
}

/// The changes waiting for the next frame.
#[derive(Debug, Default)]
pub struct Changes {
    /// Whether `queue` holds anything: the frame loop looks at this, not at the lock.
    pending: AtomicBool,
    queue: Mutex<Vec<Change>>,
}

impl Changes {
    /// Asks for `change` before the next frame; changes are made in the order asked.
    pub fn request(&self, change: Change) {
        let mut queue = self
            .queue
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        queue.push(change);
        self.pending.store(true, Ordering::Release);
    }

    /// The changes waiting.
    #[cfg(test)]
    pub fn queued(&self) -> Vec<Change> {
        self.queue
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// Makes the waiting changes on `segment`. The command reader checked them against the
    /// segment's size, so a refusal here is a bug worth a line in `report`, not a stop.
    pub fn apply(&self, segment: &mut Segment, report: &mut impl Write) {
        if !self.pending.swap(false, Ordering::Acquire) {
            return;
        }
        let changes = std::mem::take(
            &mut *self
                .queue
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        );
        for change in changes {
            let done = match change {
                Change::PowerCycle(position) => {
                    segment.power_cycle(position);
                    Ok(())
                }
                Change::Break(cable) => segment.break_cable(cable),
                Change::Kill(position) => segment.kill(position),
                Change::Heal => {
                    segment.heal();
                    Ok(())
                }
            };
            if let Err(reason) = done {
                // A closed stderr must not stop the simulator.
                let _ = writeln!(report, "ecat-sim: {change:?} not made: {reason}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::topology::{Topology, build};

    #[test]
    fn changes_wait_for_the_frame_loop_and_are_made_in_order() {
        let mut segment = build(&Topology::default_segment()).unwrap();
        segment.set_ring(true);
        let changes = Changes::default();
        changes.request(Change::Break(2));
        changes.request(Change::Kill(4));
        assert_eq!(changes.queued(), vec![Change::Break(2), Change::Kill(4)]);
        assert_eq!(
            segment.reachable(),
            5,
            "nothing changes before the loop applies it"
        );
        let mut report = Vec::new();
        changes.apply(&mut segment, &mut report);
        assert!(changes.queued().is_empty());
        assert_eq!(segment.reachable(), 2);
        assert!(!segment.slave(4).unwrap().is_powered());
        changes.request(Change::Heal);
        changes.request(Change::Break(9));
        changes.apply(&mut segment, &mut report);
        assert_eq!(segment.reachable(), 5);
        assert!(segment.slave(4).unwrap().is_powered());
        let report = String::from_utf8(report).unwrap();
        assert!(report.contains("Break(9) not made: no cable 9"), "{report}");
    }
}
