//! Emulated slaves wired in a line or a ring, processing whole Ethernet frames in place as a
//! real EtherCAT segment does.
//!
//! Wiring: cable 0 joins the master's primary port to slave 0's port 0, cable *k* joins
//! slave *k − 1*'s port 1 to slave *k*'s port 0, and in a ring (cable redundancy,
//! ETG.1000.3 §4.2, ETG.1000.4 §6) cable *len* joins the last slave's port 1 to the
//! master's backup port. A cable that is cut ([`Segment::break_cable`], or a slave
//! unplugged with [`Segment::set_plugged`], which is the same thing on cable *position*)
//! or a slave without power ([`Segment::kill`]) takes the link down on both of its ends.
//!
//! Where a frame goes is `route`'s job: an ESC forwards through its ports in the order
//! 0 → processing unit → 3 → 1 → 2 → 0 and a closed port loops back, so a frame from the
//! primary port is processed on its way out and passes unprocessed on its way back, and a
//! frame from the backup port passes unprocessed until a slave whose port 0 is closed turns
//! it into its processing unit. In a line (no ring) the last slave's port 1 is closed and
//! every frame returns on the primary port, as before rings existed. A slave whose port-1
//! loop the master closed (DL control) also turns frames back.
//!
//! Distributed-clock timing: a frame read from the time source at `now` reaches each port at
//! `now` plus the hop delays of the cables it crossed so far (crossing cable *k* costs slave
//! *k*'s `hop_delay_ns`, the backup cable the last slave's) and loops back in no time. In a
//! line a master measuring propagation delays therefore finds each slave's configured
//! `hop_delay_ns`.

mod route;
#[cfg(test)]
mod tests;
mod wiring;

use ecat_wire::ethernet::EthernetFrame;
use ecat_wire::frame::{EthercatFrame, FrameType};

use crate::device::Device;
use crate::esc::{Esc, ManualTime, TimeSource};
use ecat_wire::register::AlState;

use route::Route;

/// The locally-administered bit the first slave sets in the first source-MAC byte of the
/// frames it returns (ETG.1000.4, spec-notes §frame).
const RETURNED_MAC_BIT: u8 = 0x02;

/// The master's two ports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Port {
    /// The port cable 0 leaves from, towards slave 0's port 0.
    Primary,
    /// The redundancy port, where a ring's last cable comes back from the last slave's
    /// port 1.
    Backup,
}

/// One slave: its ESC and the application behind it.
pub struct Slave {
    esc: Esc,
    device: Box<dyn Device>,
    plugged: bool,
    powered: bool,
}

impl std::fmt::Debug for Slave {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slave")
            .field("esc", &self.esc)
            .field("plugged", &self.plugged)
            .field("powered", &self.powered)
            .finish_non_exhaustive()
    }
}

impl Slave {
    /// A slave made of `esc` and `device`, plugged in and powered.
    pub fn new(esc: Esc, device: Box<dyn Device>) -> Self {
        Slave {
            esc,
            device,
            plugged: true,
            powered: true,
        }
    }

    /// The ESC.
    pub fn esc(&self) -> &Esc {
        &self.esc
    }

    /// The ESC, for register pokes and fault injection.
    pub fn esc_mut(&mut self) -> &mut Esc {
        &mut self.esc
    }

    /// The device.
    pub fn device(&self) -> &dyn Device {
        self.device.as_ref()
    }

    /// The device, mutable.
    pub fn device_mut(&mut self) -> &mut dyn Device {
        self.device.as_mut()
    }

    /// Puts a new device behind the ESC (e.g. a fresh one after a power cycle) and returns
    /// the old one.
    pub fn replace_device(&mut self, device: Box<dyn Device>) -> Box<dyn Device> {
        std::mem::replace(&mut self.device, device)
    }

    /// Whether the cable into port 0 is connected (it is not when the slave was unplugged
    /// or that cable cut).
    pub fn is_plugged(&self) -> bool {
        self.plugged
    }

    /// Whether the slave has power (it has none after [`Segment::kill`] until
    /// [`Segment::heal`]).
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// The delay of the cable into port 0, ns.
    fn hop_ns(&self) -> u64 {
        u64::from(self.esc.config().dc.hop_delay_ns)
    }
}

/// Slaves in a line or a ring and the time base their clocks run on.
pub struct Segment {
    slaves: Vec<Slave>,
    time: Box<dyn TimeSource>,
    /// Whether the last slave's port 1 is wired to the master's backup port.
    ring: bool,
    /// Whether that last cable is connected (only meaningful in a ring).
    backup_cable: bool,
    /// The last frame's route, kept so that routing a frame does not allocate.
    route: Route,
    /// The last frame's datagram layout, kept for the same reason.
    chain: crate::esc::Chain,
}

impl std::fmt::Debug for Segment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Segment")
            .field("slaves", &self.slaves)
            .field("ring", &self.ring)
            .field("backup_cable", &self.backup_cable)
            .field("now_ns", &self.time.now_ns())
            .finish()
    }
}

impl Default for Segment {
    /// An empty segment on a [`ManualTime`] that stays at 0.
    fn default() -> Self {
        Segment::new(Box::new(ManualTime::new(0)))
    }
}

impl Segment {
    /// An empty segment on `time`, wired as a line.
    pub fn new(time: Box<dyn TimeSource>) -> Self {
        Segment {
            slaves: Vec::new(),
            time,
            ring: false,
            backup_cable: true,
            route: Route::default(),
            chain: crate::esc::Chain::default(),
        }
    }

    /// Appends a slave at the end of the line (in a ring: before the cable back to the
    /// master); returns its position.
    pub fn push(&mut self, esc: Esc, device: Box<dyn Device>) -> usize {
        self.slaves.push(Slave::new(esc, device));
        self.update_links();
        self.slaves.len() - 1
    }

    /// Number of slaves (plugged or not).
    pub fn len(&self) -> usize {
        self.slaves.len()
    }

    /// Whether the segment has no slaves.
    pub fn is_empty(&self) -> bool {
        self.slaves.is_empty()
    }

    /// The slave at `position`.
    pub fn slave(&self, position: usize) -> Option<&Slave> {
        self.slaves.get(position)
    }

    /// The slave at `position`, mutable.
    pub fn slave_mut(&mut self, position: usize) -> Option<&mut Slave> {
        self.slaves.get_mut(position)
    }

    /// The ESC of the slave at `position`.
    pub fn esc(&self, position: usize) -> Option<&Esc> {
        self.slaves.get(position).map(Slave::esc)
    }

    /// The ESC of the slave at `position`, mutable.
    pub fn esc_mut(&mut self, position: usize) -> Option<&mut Esc> {
        self.slaves.get_mut(position).map(Slave::esc_mut)
    }

    /// The current time of the segment's time base, ns.
    pub fn now_ns(&self) -> u64 {
        self.time.now_ns()
    }

    /// How many slaves a frame sent on the primary port currently passes through their
    /// processing unit (in a line: the slaves from the first up to a cut or a closed port).
    pub fn reachable(&self) -> usize {
        let mut route = Route::default();
        route.plan(self, Port::Primary, 0);
        route.processed().len()
    }

    /// Runs an Ethernet frame (without FCS) sent on the master's primary port through the
    /// segment in place (see [`Segment::process_from`]).
    ///
    /// Returns `true` when the frame came back on the primary port, which in a line is
    /// whenever at least one slave is reachable. Returns `false` when the frame is not an
    /// EtherCAT datagram frame (EtherType 0x88A4, header type 1, consistent lengths) or is
    /// lost (nothing reachable), leaving it untouched: a real segment would forward a
    /// non-EtherCAT frame unchanged or drop it (DL control bit 0), and a frame sent into an
    /// unplugged link is lost; either way the master gets no processed frame back, so the
    /// caller decides what to do with it. In a closed ring the frame comes back on the
    /// backup port instead: it is processed, and `process` returns `false`.
    pub fn process(&mut self, frame: &mut [u8]) -> bool {
        self.process_from(Port::Primary, frame) == Some(Port::Primary)
    }

    /// Runs `frame` (an Ethernet frame without FCS) entering the segment from the master's
    /// `port`; returns the master port it comes back on, or `None` when it is lost (the
    /// cable at that port is cut, a closed port takes it in, or it is no EtherCAT datagram
    /// frame; the frame is then untouched).
    ///
    /// The frame is processed in place by exactly the slaves it passes through their
    /// processing unit, in the order it passes them; a frame that comes back gets bit 0x02
    /// in its first source-MAC byte, as from a real slave. Every other powered slave lets
    /// time pass ([`Segment::idle`]'s watchdogs). Where the frame goes is decided before any
    /// slave processes it, so a datagram that changes the wiring (a DL control write
    /// closing a port) takes effect from the next frame.
    pub fn process_from(&mut self, port: Port, frame: &mut [u8]) -> Option<Port> {
        let (start, end) = match EthercatFrame::parse(frame) {
            Ok(parsed) if parsed.header.frame_type == FrameType::Datagrams => (
                parsed.payload_offset,
                parsed.payload_offset + parsed.payload.len(),
            ),
            _ => return None,
        };
        let now = self.time.now_ns();
        // The route lives in the segment to be reused; taken out while the slaves are
        // borrowed mutably.
        let mut route = std::mem::take(&mut self.route);
        route.plan(self, port, now);
        // Slaves the frame does not pass see no frame, but their watchdogs keep counting.
        for (position, slave) in self.slaves.iter_mut().enumerate() {
            if slave.powered && !route.is_processed(position) {
                slave.esc.idle(now, slave.device.as_mut());
            }
        }
        // The chain's layout is the same at every slave: read once (`esc::Chain`).
        let mut chain = std::mem::take(&mut self.chain);
        if let Some(payload) = frame.get_mut(start..end) {
            chain.read(payload);
        }
        for &(position, timing) in route.processed() {
            let (Some(slave), Some(payload)) =
                (self.slaves.get_mut(position), frame.get_mut(start..end))
            else {
                continue;
            };
            slave
                .esc
                .process_chain(payload, &chain, slave.device.as_mut(), timing);
        }
        self.chain = chain;
        let exit = route.exit();
        self.route = route;
        if exit.is_some()
            && let Ok(mut ethernet) = EthernetFrame::new_checked(&mut *frame)
        {
            let mut source = ethernet.source();
            source[0] |= RETURNED_MAC_BIT;
            ethernet.set_source(source);
        }
        exit
    }

    /// Lets time pass without a frame (a silent or cut wire): every powered slave's
    /// process-data watchdog runs out on time, as an ESC's hardware counter does, so a slave
    /// in OP that hears nothing more falls back to SAFEOP and its outputs to their safe
    /// state (spec-notes §esc.watchdog).
    pub fn idle(&mut self) {
        let now = self.time.now_ns();
        for slave in self.slaves.iter_mut().filter(|s| s.powered) {
            slave.esc.idle(now, slave.device.as_mut());
        }
    }

    /// Resets the slave at `position` as power-on does: its ESC goes back to power-on
    /// values (the SII image survives) and its application is told it is in INIT again.
    fn reset_slave(&mut self, position: usize) {
        let now = self.time.now_ns();
        let Some(slave) = self.slaves.get_mut(position) else {
            return;
        };
        let before = slave.esc.al_state();
        slave.esc.power_cycle(now);
        // The application restarts with the controller: it forgets its mailbox counters and
        // transfers as it does on the way down to INIT (a power-cycled slave is a new one).
        let ctx = slave.esc.device_context();
        let _ = slave.device.state_change(before, AlState::Init, &ctx);
    }
}
