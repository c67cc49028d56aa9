//! A line of emulated slaves processing whole Ethernet frames in place, as a real EtherCAT
//! segment does: the frame passes slave 0, 1, 2, ... and returns to the master.
//!
//! Topology is a line: slave *i*'s port 1 connects to slave *i + 1*'s port 0. Unplugging
//! slave *i* (its port 0 link goes down) hides it and every slave behind it; slave *i − 1*
//! then shows port 1 without link and loops frames back. A slave whose port-1 loop the master
//! closed (DL control) also ends the line.
//!
//! Distributed-clock timing: a frame read from the time source at `now` reaches slave *i* at
//! `now + Σ hop delays up to i` and, coming back, passes its port 1 at the mirror instant
//! (the last slave loops it back in no time). A master measuring propagation delays
//! therefore finds each slave's configured `hop_delay_ns`.

use ecat_wire::ethernet::EthernetFrame;
use ecat_wire::frame::{EthercatFrame, FrameType};

use crate::device::Device;
use crate::esc::{Esc, FrameTiming, ManualTime, TimeSource};
use ecat_wire::register::AlState;

/// The locally-administered bit the first slave sets in the first source-MAC byte of the
/// frames it returns (ETG.1000.4, spec-notes §frame).
const RETURNED_MAC_BIT: u8 = 0x02;

/// One slave: its ESC and the application behind it.
pub struct Slave {
    esc: Esc,
    device: Box<dyn Device>,
    plugged: bool,
}

impl std::fmt::Debug for Slave {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slave")
            .field("esc", &self.esc)
            .field("plugged", &self.plugged)
            .finish_non_exhaustive()
    }
}

impl Slave {
    /// A slave made of `esc` and `device`, plugged in.
    pub fn new(esc: Esc, device: Box<dyn Device>) -> Self {
        Slave {
            esc,
            device,
            plugged: true,
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

    /// Whether the link into port 0 is up.
    pub fn is_plugged(&self) -> bool {
        self.plugged
    }
}

/// Slaves in a line and the time base their clocks run on.
pub struct Segment {
    slaves: Vec<Slave>,
    time: Box<dyn TimeSource>,
}

impl std::fmt::Debug for Segment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Segment")
            .field("slaves", &self.slaves)
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
    /// An empty segment on `time`.
    pub fn new(time: Box<dyn TimeSource>) -> Self {
        Segment {
            slaves: Vec::new(),
            time,
        }
    }

    /// Appends a slave at the end of the line; returns its position.
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

    /// Plugs or unplugs the cable into the port 0 of the slave at `position`. Unplugged, it
    /// and every slave behind it see no frames; the slave before it shows port 1 without
    /// link. Link losses count in both ends' lost-link counters.
    pub fn set_plugged(&mut self, position: usize, plugged: bool) {
        if let Some(slave) = self.slaves.get_mut(position) {
            slave.plugged = plugged;
            self.update_links();
        }
    }

    /// Power-cycles the slave at `position`: its ESC goes back to power-on values (the SII
    /// image survives) and its neighbours see their links to it drop and come back. The
    /// device is not reset (the [`Device`] trait has no reset; use
    /// [`Slave::replace_device`] for a fresh one); its queued mailbox messages are dropped
    /// with the ESC's mailbox.
    pub fn power_cycle(&mut self, position: usize) {
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
        if slave.plugged && position > 0 {
            let previous = &mut self.slaves[position - 1].esc;
            previous.set_link(1, false);
            previous.set_link(1, true);
        }
        if let Some(next) = self.slaves.get_mut(position + 1)
            && next.plugged
        {
            next.esc.set_link(0, false);
            next.esc.set_link(0, true);
        }
    }

    /// How many slaves, from the first, a frame currently passes.
    pub fn reachable(&self) -> usize {
        let mut count = 0;
        for slave in &self.slaves {
            if !slave.plugged {
                break;
            }
            count += 1;
            if !slave.esc.forwards_to_port1() {
                break;
            }
        }
        count
    }

    /// Runs an Ethernet frame (without FCS) through the segment in place: every reachable
    /// slave processes every datagram, then the first source-MAC byte gets bit 0x02 as from
    /// a real first slave.
    ///
    /// Returns `false`, leaving the frame untouched, when the frame is not an EtherCAT
    /// datagram frame (EtherType 0x88A4, header type 1, consistent lengths) or no slave is
    /// reachable. A real segment would forward a non-EtherCAT frame unchanged or drop it
    /// (DL control bit 0), and a frame sent into an unplugged link is lost; either way the
    /// master gets no processed frame back, so the caller decides what to do with it.
    pub fn process(&mut self, frame: &mut [u8]) -> bool {
        let (start, end) = match EthercatFrame::parse(frame) {
            Ok(parsed) if parsed.header.frame_type == FrameType::Datagrams => (
                parsed.payload_offset,
                parsed.payload_offset + parsed.payload.len(),
            ),
            _ => return false,
        };
        let count = self.reachable();
        let now = self.time.now_ns();
        // Slaves behind a cut see no frame, but their watchdogs keep counting.
        for slave in &mut self.slaves[count..] {
            slave.esc.idle(now, slave.device.as_mut());
        }
        if count == 0 {
            return false;
        }
        let hop = |slave: &Slave| u64::from(slave.esc.config().dc.hop_delay_ns);
        let last = self.slaves[..count]
            .iter()
            .fold(now, |t, s| t.saturating_add(hop(s)));
        let mut arrival = now;
        for (position, slave) in self.slaves[..count].iter_mut().enumerate() {
            arrival = arrival.saturating_add(hop(slave));
            let port1_ns =
                (position + 1 < count).then(|| last.saturating_add(last.saturating_sub(arrival)));
            let Some(payload) = frame.get_mut(start..end) else {
                return false;
            };
            let timing = FrameTiming {
                port0_ns: arrival,
                port1_ns,
            };
            slave
                .esc
                .process_frame(payload, slave.device.as_mut(), timing);
        }
        if let Ok(mut ethernet) = EthernetFrame::new_checked(&mut *frame) {
            let mut source = ethernet.source();
            source[0] |= RETURNED_MAC_BIT;
            ethernet.set_source(source);
        }
        true
    }

    /// Lets time pass without a frame (a silent or cut wire): every slave's process-data
    /// watchdog runs out on time, as an ESC's hardware counter does, so a slave in OP that
    /// hears nothing more falls back to SAFEOP and its outputs to their safe state
    /// (spec-notes §esc.watchdog).
    pub fn idle(&mut self) {
        let now = self.time.now_ns();
        for slave in &mut self.slaves {
            slave.esc.idle(now, slave.device.as_mut());
        }
    }

    /// Sets every ESC's port links from the plug states: slave *i*'s port 0 is up when it
    /// is plugged, its port 1 when slave *i + 1* exists and is plugged.
    fn update_links(&mut self) {
        let plugged: Vec<bool> = self.slaves.iter().map(|s| s.plugged).collect();
        for (i, slave) in self.slaves.iter_mut().enumerate() {
            slave.esc.set_link(0, plugged[i]);
            slave
                .esc
                .set_link(1, plugged.get(i + 1).copied().unwrap_or(false));
        }
    }
}
