//! A **test double** of an EtherCAT segment: a few fake slaves, each a flat byte array,
//! that process datagram frames the way the command table (spec-notes §commands) says (addressing, ADP
//! increments, BRD's OR, read-write exchange, read-multiple-write, logical windows, working
//! counter increments).
//!
//! It knows nothing of SyncManagers, FMMUs, AL states or the SII: it exists only so that
//! the bus tests have something on the other end of the link. The real emulated slave
//! controller lives in the `sim` crate and replaces this in later tests.

use master_core::wire::command::{AddressingMode, Command};
use master_core::wire::datagram::{Datagram, DatagramsMut};
use master_core::wire::frame::EthercatFrame;

/// Bytes of memory per fake slave (registers and "process RAM").
pub const MEM_LEN: usize = 0x2000;
/// Where a slave's logical window writes its outputs.
pub const OUTPUTS_AT: usize = 0x1000;
/// Where a slave's logical window reads its inputs from.
pub const INPUTS_AT: usize = 0x1100;
/// Start of the first slave's logical window; each slave's window follows the previous.
pub const LOGICAL_START: u32 = 0x0001_0000;
/// Output bytes, then input bytes, in every slave's logical window.
pub const WINDOW_OUTPUTS: usize = 4;
/// Input bytes in every slave's logical window.
pub const WINDOW_INPUTS: usize = 4;
/// Bytes of one slave's logical window.
pub const WINDOW_LEN: usize = WINDOW_OUTPUTS + WINDOW_INPUTS;

/// Station address register.
const STATION_ADDRESS: usize = 0x0010;

/// One fake slave.
#[derive(Debug, Clone)]
pub struct FakeSlave {
    /// Registers and memory, [`MEM_LEN`] bytes.
    pub mem: Vec<u8>,
    /// Logical addresses `[start, start + WINDOW_OUTPUTS)` are written to [`OUTPUTS_AT`],
    /// `[start + WINDOW_OUTPUTS, start + WINDOW_LEN)` read from [`INPUTS_AT`].
    pub window_start: u32,
}

impl FakeSlave {
    fn station(&self) -> u16 {
        u16::from_le_bytes([self.mem[STATION_ADDRESS], self.mem[STATION_ADDRESS + 1]])
    }

    fn range(&self, ado: u16, len: usize) -> Option<std::ops::Range<usize>> {
        let start = usize::from(ado);
        (start + len <= self.mem.len()).then_some(start..start + len)
    }

    /// What this slave does to one passing datagram.
    fn apply(&mut self, datagram: &mut Datagram<&mut [u8]>) {
        let command = datagram.command();
        let len = usize::from(datagram.length());
        let ado = datagram.ado();
        let adp = datagram.adp();
        let (addressed, increments) = match command.addressing() {
            AddressingMode::Position => (adp == 0, true),
            AddressingMode::Node => (adp == self.station(), false),
            AddressingMode::Broadcast => (true, true),
            AddressingMode::Logical => {
                self.apply_logical(datagram);
                return;
            }
            AddressingMode::None => return,
        };
        if increments {
            datagram.set_adp(adp.wrapping_add(1));
        }
        let Some(range) = self.range(ado, len) else {
            return;
        };
        let (read, write) = match command {
            Command::Aprd | Command::Fprd => (addressed, false),
            Command::Apwr | Command::Fpwr | Command::Bwr => (false, addressed),
            Command::Aprw | Command::Fprw | Command::Brw => (addressed, addressed),
            Command::Brd => (true, false),
            // The addressed slave reads, every other one writes.
            Command::Armw | Command::Frmw => (addressed, !addressed),
            _ => (false, false),
        };
        let received = datagram.data().to_vec();
        let mut wkc = 0;
        if read {
            let data = datagram.data_mut();
            if matches!(command, Command::Brd | Command::Brw) {
                for (out, byte) in data.iter_mut().zip(&self.mem[range.clone()]) {
                    *out |= byte;
                }
            } else {
                data.copy_from_slice(&self.mem[range.clone()]);
            }
            wkc += 1;
        }
        if write {
            self.mem[range].copy_from_slice(&received);
            wkc += if read { 2 } else { 1 };
        }
        if matches!(command, Command::Armw | Command::Frmw) && wkc > 0 {
            // One increment per slave, whether it read or wrote.
            wkc = 1;
        }
        datagram.set_wkc(datagram.wkc().wrapping_add(wkc));
    }

    /// LRD/LWR/LRW against this slave's window; writes take the data as received.
    fn apply_logical(&mut self, datagram: &mut Datagram<&mut [u8]>) {
        let command = datagram.command();
        let start = datagram.address();
        let len = usize::from(datagram.length());
        let received = datagram.data().to_vec();
        let mut wkc = 0;
        let mut read_hit = false;
        let mut write_hit = false;
        for (i, byte) in received.iter().enumerate() {
            let logical = start.wrapping_add(i as u32);
            let Some(offset) = logical.checked_sub(self.window_start) else {
                continue;
            };
            let offset = offset as usize;
            if offset < WINDOW_OUTPUTS && matches!(command, Command::Lwr | Command::Lrw) {
                self.mem[OUTPUTS_AT + offset] = *byte;
                write_hit = true;
            } else if (WINDOW_OUTPUTS..WINDOW_LEN).contains(&offset)
                && matches!(command, Command::Lrd | Command::Lrw)
                && i < len
            {
                datagram.data_mut()[i] = self.mem[INPUTS_AT + offset - WINDOW_OUTPUTS];
                read_hit = true;
            }
        }
        if read_hit {
            wkc += 1;
        }
        if write_hit {
            wkc += if command == Command::Lrw { 2 } else { 1 };
        }
        datagram.set_wkc(datagram.wkc().wrapping_add(wkc));
    }
}

/// A line of fake slaves.
#[derive(Debug, Clone)]
pub struct FakeSegment {
    /// The slaves, in ring order.
    pub slaves: Vec<FakeSlave>,
}

impl FakeSegment {
    /// `count` slaves with station addresses 0x1001, 0x1002, ... already set, memory
    /// filled with [`FakeSegment::pattern`], and consecutive logical windows from
    /// [`LOGICAL_START`].
    pub fn new(count: usize) -> FakeSegment {
        let slaves = (0..count)
            .map(|slave| {
                let mut mem: Vec<u8> = (0..MEM_LEN).map(|at| Self::pattern(slave, at)).collect();
                let station = Self::station(slave).to_le_bytes();
                mem[STATION_ADDRESS..STATION_ADDRESS + 2].copy_from_slice(&station);
                FakeSlave {
                    mem,
                    window_start: LOGICAL_START + (slave * WINDOW_LEN) as u32,
                }
            })
            .collect();
        FakeSegment { slaves }
    }

    /// The station address of the slave at `position`.
    pub fn station(position: usize) -> u16 {
        0x1001 + position as u16
    }

    /// The initial byte at `offset` of slave `slave` (except the station address at
    /// 0x0010..0x0012): different for every slave and nearby offset.
    pub fn pattern(slave: usize, offset: usize) -> u8 {
        (slave as u8).wrapping_mul(0x35) ^ (offset as u8) ^ ((offset >> 8) as u8).wrapping_mul(7)
    }

    /// Processes a frame in place, as it passes every slave and comes back. Returns false
    /// (frame left as it was or partly processed) if it is not a well-formed datagram frame.
    pub fn process(&mut self, frame: &mut [u8]) -> bool {
        let Ok(parsed) = EthercatFrame::parse(frame) else {
            return false;
        };
        if parsed.datagrams().is_err() {
            return false;
        }
        let start = parsed.payload_offset;
        let end = start + usize::from(parsed.header.length);
        for datagram in DatagramsMut::new(&mut frame[start..end]) {
            let Ok(mut datagram) = datagram else {
                return false;
            };
            for slave in &mut self.slaves {
                slave.apply(&mut datagram);
            }
        }
        // The first slave marks the source MAC as locally administered (spec-notes §frame), so
        // nothing may filter returning frames by their source address.
        frame[6] |= 0x02;
        true
    }
}
