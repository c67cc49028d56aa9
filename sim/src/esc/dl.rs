//! Data-link layer state: port links, DL status 0x0110 and the error counters 0x0300-0x0313
//! (ETG.1000.4, spec-notes §esc.dl, §esc.errors).
//!
//! The ESC is modelled with two ports: port 0 towards the master, port 1 towards the next
//! slave (or, the last slave of a ring, the master's backup port). Port 0 is open while it
//! has a link and closed (looped back, as "auto" does) without one, which only a ring can
//! make use of: a frame coming in at port 1 then turns into the processing unit (see
//! `segment::route`). Port 1 follows its DL control loop setting: "auto" closes it when
//! there is no link, "closed" closes it always, "open" keeps it open (and frames sent into
//! a port without link are treated as looped back, not lost). Ports 2 and 3 do not exist
//! and show a closed loop.

use ecat_wire::register::address as reg;
use ecat_wire::register::dl::{DlControl, DlStatus, LoopMode, PortStatus};

use super::Esc;
use super::memory::overlaps;

/// An error counter that can be bumped for fault injection (spec-notes §esc.errors). Ports are 0-3;
/// counters saturate at 255.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorCounter {
    /// Invalid frame (CRC) counter of a port, 0x0300 + 2n.
    InvalidFrame(u8),
    /// RX error (PHY) counter of a port, 0x0301 + 2n.
    RxError(u8),
    /// Forwarded RX error counter of a port, 0x0308 + n.
    ForwardedRxError(u8),
    /// ECAT processing unit error counter, 0x030C.
    ProcessingUnit,
    /// PDI error counter, 0x030D.
    Pdi,
    /// Lost link counter of a port, 0x0310 + n.
    LostLink(u8),
}

impl ErrorCounter {
    /// The counter's register address, `None` for a port above 3.
    pub fn address(self) -> Option<u16> {
        let port = |p: u8, base: u16, stride: u16| (p < 4).then(|| base + stride * u16::from(p));
        match self {
            ErrorCounter::InvalidFrame(p) => port(p, reg::RX_ERROR_COUNTERS, 2),
            ErrorCounter::RxError(p) => port(p, reg::RX_ERROR_COUNTERS + 1, 2),
            ErrorCounter::ForwardedRxError(p) => port(p, reg::FORWARDED_RX_ERROR_COUNTERS, 1),
            ErrorCounter::ProcessingUnit => Some(reg::PROCESSING_UNIT_ERROR_COUNTER),
            ErrorCounter::Pdi => Some(reg::PDI_ERROR_COUNTER),
            ErrorCounter::LostLink(p) => port(p, reg::LOST_LINK_COUNTERS, 1),
        }
    }
}

/// Physical link state of ports 0 and 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Ports {
    link: [bool; 2],
}

impl Ports {
    /// Link on port 0 (the slave is plugged in), none on port 1.
    pub fn new() -> Self {
        Ports {
            link: [true, false],
        }
    }
}

/// Counters a write clears together: the invalid-frame and RX error counters of all ports
/// are one group (ETG.1000.4, spec-notes §esc.errors); every other counter is cleared on its own.
const RX_ERROR_GROUP: (u16, usize) = (reg::RX_ERROR_COUNTERS, 12);
const SINGLE_COUNTERS: [u16; 8] = [
    reg::PROCESSING_UNIT_ERROR_COUNTER,
    reg::PDI_ERROR_COUNTER,
    reg::LOST_LINK_COUNTERS,
    reg::LOST_LINK_COUNTERS + 1,
    reg::LOST_LINK_COUNTERS + 2,
    reg::LOST_LINK_COUNTERS + 3,
    reg::WATCHDOG_COUNTER_PROCESS_DATA,
    reg::WATCHDOG_COUNTER_PDI,
];

impl Esc {
    /// Adds one to an error counter (saturating at 255).
    pub fn count_error(&mut self, counter: ErrorCounter) {
        if let Some(addr) = counter.address() {
            let addr = u32::from(addr);
            let value = self.mem.u8(addr).saturating_add(1);
            self.mem.set_u8(addr, value);
        }
    }

    /// Whether port `port` (0 or 1) has a link.
    pub fn link(&self, port: usize) -> bool {
        self.ports.link.get(port).copied().unwrap_or(false)
    }

    /// Sets the physical link of port `port` (0 or 1). Losing a link counts in the port's
    /// lost-link counter; any change raises the DL status change event.
    pub fn set_link(&mut self, port: usize, up: bool) {
        let Some(link) = self.ports.link.get_mut(port) else {
            return;
        };
        if *link == up {
            return;
        }
        *link = up;
        if !up {
            self.count_error(ErrorCounter::LostLink(port as u8));
        }
        self.events.dl_status = true;
        self.update_dl_status();
    }

    fn port1_loop_closed(&self) -> bool {
        let control = DlControl::decode(self.mem.u32(reg::DL_CONTROL.into()));
        match control.loop_modes[1] {
            LoopMode::Closed => true,
            LoopMode::Open => false,
            LoopMode::Auto | LoopMode::AutoClose => !self.link(1),
        }
    }

    /// Whether a frame leaves through port 1 to the next slave: link up and loop open.
    pub fn forwards_to_port1(&self) -> bool {
        self.link(1) && !self.port1_loop_closed()
    }

    /// Recomputes DL status 0x0110 from the links, loop settings and EEPROM state.
    pub(crate) fn update_dl_status(&mut self) {
        let closed_port = PortStatus {
            link: false,
            loop_closed: true,
            communication: false,
        };
        let status = DlStatus {
            pdi_operational: self.eeprom.loaded(),
            pdi_watchdog_ok: true,
            enhanced_link_detection: false,
            ports: [
                PortStatus {
                    link: self.link(0),
                    loop_closed: !self.link(0),
                    communication: self.link(0),
                },
                PortStatus {
                    link: self.link(1),
                    loop_closed: self.port1_loop_closed(),
                    communication: self.link(1),
                },
                closed_port,
                closed_port,
            ],
        };
        self.mem.set_u16(reg::DL_STATUS.into(), status.encode());
    }

    /// A write touched `[addr, addr + len)`: clear the counters it hit.
    pub(crate) fn clear_error_counters(&mut self, addr: u32, len: usize) {
        let (group, group_len) = RX_ERROR_GROUP;
        if overlaps(addr, len, group.into(), group_len)
            && let Some(bytes) = self.mem.get_mut(group.into(), group_len)
        {
            bytes.fill(0);
        }
        for counter in SINGLE_COUNTERS {
            if overlaps(addr, len, counter.into(), 1) {
                self.mem.set_u8(counter.into(), 0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use ecat_wire::command::Command;

    #[test]
    fn dl_status_follows_the_topology() {
        let (mut esc, mut dev) = slave();
        assert_eq!(
            esc.read_u16(0x0110),
            0x5613,
            "end of line: port 1 loop closed"
        );
        let status = DlStatus::decode(esc.read_u16(0x0110));
        assert_eq!(status.active_ports(), 1);
        esc.set_link(1, true);
        assert_eq!(
            esc.read_u16(0x0110),
            0x5A33,
            "port 1 link, communication, open"
        );
        assert!(esc.forwards_to_port1());
        // The master forces port 1 closed (0x0101 bits 2-3 = 11).
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0101, &[0x0C]);
        assert!(!esc.forwards_to_port1());
        assert_eq!(esc.read_u16(0x0110) & 0x0C00, 0x0C00);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0101, &[0x00]);
        esc.set_link(1, false);
        assert_eq!(esc.read_u8(0x0311), 1, "lost link on port 1");
    }

    #[test]
    fn counters_saturate_and_clear_on_write() {
        let (mut esc, mut dev) = slave();
        for _ in 0..300 {
            esc.count_error(ErrorCounter::InvalidFrame(1));
        }
        esc.count_error(ErrorCounter::RxError(0));
        esc.count_error(ErrorCounter::LostLink(0));
        esc.count_error(ErrorCounter::LostLink(7));
        assert_eq!(esc.read_u8(0x0302), 255);
        assert_eq!(esc.read_u8(0x0301), 1);
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x0300, &[0; 20]);
        assert_eq!((r.data[1], r.data[2], r.data[16]), (1, 255, 1));
        // Writing one byte of the RX group clears the whole group, not the lost-link ones.
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0300, &[0x55]);
        assert_eq!(esc.read_u8(0x0302), 0);
        assert_eq!(esc.read_u8(0x0301), 0);
        assert_eq!(esc.read_u8(0x0310), 1);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0310, &[0x55]);
        assert_eq!(esc.read_u8(0x0310), 0);
    }
}
