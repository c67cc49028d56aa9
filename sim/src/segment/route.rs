//! Where a frame goes: the walk through the ESCs' ports (ETG.1000.3 §4.2, ETG.1000.4 §6;
//! spec-notes §esc.dl).
//!
//! An ESC forwards a frame through its ports in the order 0 → processing unit → 3 → 1 → 2 →
//! 0, and a closed port (no link, or its loop closed by DL control) hands the frame straight
//! to the next port in that order. The emulated ESC has ports 0 and 1 only (2 and 3 are
//! always closed), so:
//! - a frame coming in at port 0 is processed, then leaves through port 1 if it is open, or
//!   loops back and leaves through port 0 unprocessed;
//! - a frame coming in at port 1 leaves through port 0 unprocessed if port 0 has a link;
//!   otherwise it loops back into the processing unit, is processed and leaves through
//!   port 1.
//!
//! The walk is planned before any slave processes the frame, so every slave's
//! [`FrameTiming`] (when the frame reaches its processing unit, when it comes in at port 1)
//! is known when it processes it. Timing: crossing cable *k* (into slave *k*'s port 0, or
//! back out of it) costs slave *k*'s `hop_delay_ns`; the backup cable costs the last
//! slave's; a loop-back costs nothing, and so does passing an ESC. This is an
//! approximation: a real ESC adds its forwarding delay at every pass, and the two
//! directions of a cable are not always equal. A frame coming in at a closed port is lost,
//! as is one that would turn round a second time; a real ESC marks a frame that passes a
//! closed port 0 as circulating and destroys it the second time. That bit is not modelled
//! (the frame bytes are left alone): one turn-round per frame is all a line or a ring with
//! one master allows, so only a DL control loop setting could make a second one.

use super::{Port, Segment, Slave};
use crate::esc::FrameTiming;

/// Where the frame is between two steps of the walk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    /// Coming in at port 0 of the slave at this position.
    IntoPort0(usize),
    /// Coming in at port 1 of the slave at this position.
    IntoPort1(usize),
    /// Leaving the processing unit of this slave towards port 1 (port 3 is closed).
    OutOfPort1(usize),
    /// Leaving towards port 0 of this slave (port 2 is closed).
    OutOfPort0(usize),
    /// Back at the master.
    Master(Port),
    /// Nowhere: into a cut cable, a closed port or a second turn-round.
    Lost,
}

/// The walk of one frame: which slaves process it, in which order and when, and where it
/// ends. Its buffers are reused from frame to frame.
#[derive(Debug, Default)]
pub(super) struct Route {
    /// (position, timing) of every processing-unit pass, in order.
    processed: Vec<(usize, FrameTiming)>,
    /// When the frame first came in at each slave's port 1, by position.
    port1_ns: Vec<Option<u64>>,
    /// Whether each slave processed the frame, by position.
    was_processed: Vec<bool>,
    exit: Option<Port>,
}

impl Route {
    /// Plans the walk of a frame entering from the master's `port` at `now` ns.
    pub fn plan(&mut self, segment: &Segment, port: Port, now: u64) {
        let slaves = &segment.slaves;
        let len = slaves.len();
        self.processed.clear();
        self.port1_ns.clear();
        self.port1_ns.resize(len, None);
        self.was_processed.clear();
        self.was_processed.resize(len, false);
        self.exit = None;
        let hop = |cable: usize| {
            slaves
                .get(cable)
                .or_else(|| slaves.last())
                .map_or(0, Slave::hop_ns)
        };
        let mut t = now;
        let mut step = match port {
            // Crossing cable 0, or in an empty ring the one cable between the two ports.
            Port::Primary if segment.cable_up(0) => {
                t = t.saturating_add(hop(0));
                if len == 0 {
                    Step::Master(Port::Backup)
                } else {
                    Step::IntoPort0(0)
                }
            }
            Port::Backup if segment.cable_up(len) => {
                t = t.saturating_add(hop(len));
                match len.checked_sub(1) {
                    Some(last) => Step::IntoPort1(last),
                    None => Step::Master(Port::Primary),
                }
            }
            _ => Step::Lost,
        };
        // Each slave is entered at most twice and left at most twice on a walk with one
        // turn-round; the bound only guards against a bug, never cuts a real walk short.
        for _ in 0..=4 * len + 4 {
            step = match step {
                Step::Master(port) => {
                    self.exit = Some(port);
                    return;
                }
                Step::Lost => return,
                Step::IntoPort0(p) => match slaves.get(p) {
                    Some(slave) if slave.powered && slave.esc.link(0) => self.pass(p, t),
                    _ => Step::Lost,
                },
                Step::IntoPort1(p) => match slaves.get(p) {
                    Some(slave) if slave.powered && slave.esc.forwards_to_port1() => {
                        if let Some(seen) = self.port1_ns.get_mut(p) {
                            seen.get_or_insert(t);
                        }
                        if slave.esc.link(0) {
                            Step::OutOfPort0(p)
                        } else {
                            // Port 0 is closed: round into the processing unit.
                            self.pass(p, t)
                        }
                    }
                    _ => Step::Lost,
                },
                Step::OutOfPort1(p) => match slaves.get(p) {
                    Some(slave) if slave.esc.forwards_to_port1() => {
                        t = t.saturating_add(hop(p + 1));
                        if p + 1 < len {
                            Step::IntoPort0(p + 1)
                        } else {
                            Step::Master(Port::Backup)
                        }
                    }
                    // Port 1 closed: through port 2 (closed) back to port 0.
                    Some(_) => Step::OutOfPort0(p),
                    None => Step::Lost,
                },
                Step::OutOfPort0(p) => match slaves.get(p) {
                    Some(slave) if slave.esc.link(0) => {
                        t = t.saturating_add(hop(p));
                        match p.checked_sub(1) {
                            Some(previous) => Step::IntoPort1(previous),
                            None => Step::Master(Port::Primary),
                        }
                    }
                    // Both ports closed: the frame would circulate in this slave.
                    _ => Step::Lost,
                },
            };
        }
    }

    /// The frame reaches slave `p`'s processing unit at `t`: recorded, unless it already
    /// passed there (a second turn-round, lost).
    fn pass(&mut self, p: usize, t: u64) -> Step {
        match self.was_processed.get_mut(p) {
            Some(seen) if !*seen => {
                *seen = true;
                self.processed.push((
                    p,
                    FrameTiming {
                        port0_ns: t,
                        port1_ns: None,
                    },
                ));
                Step::OutOfPort1(p)
            }
            _ => Step::Lost,
        }
    }

    /// The processing-unit passes in order, each with its timing (the time the frame came
    /// in at port 1 filled in, before or after the pass).
    pub fn processed(&mut self) -> &[(usize, FrameTiming)] {
        for (position, timing) in &mut self.processed {
            timing.port1_ns = self.port1_ns.get(*position).copied().flatten();
        }
        &self.processed
    }

    /// Whether the slave at `position` processes the frame.
    pub fn is_processed(&self, position: usize) -> bool {
        self.was_processed.get(position).copied().unwrap_or(false)
    }

    /// The master port the frame comes back on, `None` when it is lost.
    pub fn exit(&self) -> Option<Port> {
        self.exit
    }
}
