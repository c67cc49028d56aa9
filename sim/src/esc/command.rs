//! The 15 datagram commands: who is addressed, what they do, and how the working counter
//! grows (ETG.1000.4, ETG.1000.3, spec-notes §commands, §addressing).
//!
//! - Position commands (APxx, ARMW) and broadcasts increment ADP in every slave; the slave
//!   that sees ADP == 0 is addressed.
//! - Node commands (FPxx, FRMW) match the station address 0x0010, or the alias 0x0012 when
//!   DL control bit 24 (0x0103 bit 0) is set; ADP is not modified.
//! - Reads copy (or, for BRD/BRW, OR) memory into the data: +1. Writes: +1, or +2 in the
//!   read-write commands. xRW exchange: the data returns the old content and memory takes
//!   the data as received.
//! - ARMW/FRMW: the addressed slave reads, every other slave writes: +1 each.
//! - Logical commands go through the FMMUs ([`super::fmmu`]): one increment per direction
//!   per slave however many FMMUs hit.
//! - Every slave ORs its pending ECAT events (0x0210 & 0x0200) into the IRQ field.

use ecat_wire::command::Command;
use ecat_wire::datagram::Datagram;
use ecat_wire::register::address as reg;

use crate::device::Device;

use super::Esc;
use super::physical::Origin;

/// What a physical command does at the addressed slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Op {
    /// Copy memory into the data.
    Read,
    /// OR memory into the data (BRD).
    ReadOr,
    /// Copy the data into memory.
    Write,
    /// Return the old content, store the received data (APRW, FPRW).
    Exchange,
    /// OR the old content into the data, store the received data (BRW).
    ExchangeOr,
}

impl Esc {
    /// Processes one datagram in place: data, ADP, IRQ and working counter. Device calls
    /// (mailbox delivery, outputs, inputs, state changes) happen before it returns.
    ///
    /// The view must have passed `check_len` (as [`Datagram::new_checked`] and
    /// [`ecat_wire::datagram::DatagramsMut`] ensure); DC times refer to the frame
    /// last passed to [`Esc::process_frame`].
    pub fn process_datagram(
        &mut self,
        datagram: &mut Datagram<&mut [u8]>,
        device: &mut dyn Device,
    ) {
        let mask = self.mem.u16(reg::ECAT_EVENT_MASK.into());
        // Hundreds of slaves see every datagram: the events are gathered only if a mask
        // lets any through.
        if mask != 0 {
            datagram.set_irq(datagram.irq() | (self.ecat_event_request() & mask));
        }
        let command = datagram.command();
        let adp = datagram.adp();
        let ado = datagram.ado();
        let increment = match command {
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
                datagram.set_adp(adp.wrapping_add(1));
                let addressed = adp == 0;
                match rmw_or(command, addressed) {
                    Some(op) => self.physical(device, ado, datagram.data_mut(), op),
                    None => 0,
                }
            }
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => {
                let addressed = self.node_matches(adp);
                match rmw_or(command, addressed) {
                    Some(op) => self.physical(device, ado, datagram.data_mut(), op),
                    None => 0,
                }
            }
            Command::Brd | Command::Bwr | Command::Brw => {
                datagram.set_adp(adp.wrapping_add(1));
                let op = match command {
                    Command::Brd => Op::ReadOr,
                    Command::Bwr => Op::Write,
                    _ => Op::ExchangeOr,
                };
                self.physical(device, ado, datagram.data_mut(), op)
            }
            Command::Lrd | Command::Lwr | Command::Lrw => {
                let address = datagram.address();
                let read = command != Command::Lwr;
                let write = command != Command::Lrd;
                let (read_hit, write_hit) =
                    self.logical(device, address, datagram.data_mut(), read, write);
                let write_weight = if command == Command::Lrw { 2 } else { 1 };
                u16::from(read_hit) + write_weight * u16::from(write_hit)
            }
            Command::Nop | Command::Unknown(_) => 0,
        };
        datagram.set_wkc(datagram.wkc().wrapping_add(increment));
        // Only a datagram that read or wrote this slave's memory can have changed what its
        // mailbox firmware sees (time-due replies are posted at the start of each frame).
        if increment != 0 {
            self.service_mailbox(device);
        }
    }

    /// Whether a node-addressed datagram with `adp` is for this slave.
    fn node_matches(&self, adp: u16) -> bool {
        let alias_enabled = self.mem.u8(reg::DL_CONTROL_ALIAS.into()) & 0x01 != 0;
        adp == self.station_address() || (alias_enabled && adp == self.station_alias())
    }

    /// Runs `op` on the physical memory at `ado`; returns the working-counter increment.
    fn physical(&mut self, device: &mut dyn Device, ado: u16, data: &mut [u8], op: Op) -> u16 {
        let addr = u32::from(ado);
        match op {
            Op::Read => u16::from(self.read_phys(device, addr, data, Origin::Physical)),
            Op::Write => u16::from(self.write_phys(device, addr, data, Origin::Physical)),
            Op::ReadOr => {
                let mut old = self.take_scratch(data.len());
                let read = self.read_phys(device, addr, &mut old, Origin::Physical);
                if read {
                    data.iter_mut().zip(&old).for_each(|(d, o)| *d |= o);
                }
                self.scratch = old;
                u16::from(read)
            }
            Op::Exchange => {
                let mut received = self.take_scratch(0);
                received.extend_from_slice(data);
                let read = self.read_phys(device, addr, data, Origin::Physical);
                let written = self.write_phys(device, addr, &received, Origin::Physical);
                self.scratch = received;
                u16::from(read) + 2 * u16::from(written)
            }
            Op::ExchangeOr => {
                let mut received = self.take_scratch(0);
                received.extend_from_slice(data);
                let mut old = std::mem::take(&mut self.scratch2);
                old.clear();
                old.resize(data.len(), 0);
                let read = self.read_phys(device, addr, &mut old, Origin::Physical);
                let written = self.write_phys(device, addr, &received, Origin::Physical);
                if read {
                    data.iter_mut().zip(&old).for_each(|(d, o)| *d |= o);
                }
                self.scratch = received;
                self.scratch2 = old;
                u16::from(read) + 2 * u16::from(written)
            }
        }
    }

    /// The reusable scratch buffer, cleared and zero-filled to `len` bytes. The caller puts
    /// it back into `self.scratch` when done.
    pub(crate) fn take_scratch(&mut self, len: usize) -> Vec<u8> {
        let mut buf = std::mem::take(&mut self.scratch);
        buf.clear();
        buf.resize(len, 0);
        buf
    }
}

/// The operation of a position or node command at a slave that is (or is not) addressed:
/// plain commands act only when addressed; read-multiple-write reads when addressed and
/// writes everywhere else.
fn rmw_or(command: Command, addressed: bool) -> Option<Op> {
    match (command, addressed) {
        (Command::Armw | Command::Frmw, true) => Some(Op::Read),
        (Command::Armw | Command::Frmw, false) => Some(Op::Write),
        (_, false) => None,
        (Command::Aprd | Command::Fprd, true) => Some(Op::Read),
        (Command::Apwr | Command::Fpwr, true) => Some(Op::Write),
        (_, true) => Some(Op::Exchange),
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use ecat_wire::command::Command;

    #[test]
    fn position_commands_increment_adp_and_address_adp_zero() {
        let (mut esc, mut dev) = slave();
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0xFFFF, 0x0000, &[0; 2]);
        assert_eq!((r.adp, r.wkc, r.data.as_slice()), (0, 0, &[0u8, 0][..]));
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x0000, &[0; 2]);
        assert_eq!((r.adp, r.wkc), (1, 1));
        assert_eq!(r.data, vec![0x04, 0x01]);
    }

    #[test]
    fn node_commands_match_station_and_alias_only_when_enabled() {
        let (mut esc, mut dev) = slave_with_alias(0x0777);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0010, &[0x01, 0x10]);
        let r = exec(&mut esc, &mut dev, Command::Fprd, 0x1001, 0x0010, &[0; 2]);
        assert_eq!((r.wkc, r.adp), (1, 0x1001), "ADP unchanged");
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Fprd, 0x0777, 0x0010, &[0; 2]).wkc,
            0
        );
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0103, &[0x01]);
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Fprd, 0x0777, 0x0010, &[0; 2]).wkc,
            1
        );
        assert_eq!(
            exec(&mut esc, &mut dev, Command::Fprd, 0x1001, 0x0010, &[0; 2]).wkc,
            1
        );
    }

    #[test]
    fn read_write_commands_count_three_and_exchange() {
        let (mut esc, mut dev) = slave();
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0010, &[0x01, 0x10]);
        let r = exec(&mut esc, &mut dev, Command::Aprw, 0, 0x0010, &[0x02, 0x10]);
        assert_eq!((r.wkc, r.data.as_slice()), (3, &[0x01u8, 0x10][..]));
        let r = exec(
            &mut esc,
            &mut dev,
            Command::Fprw,
            0x1002,
            0x0010,
            &[0x03, 0x10],
        );
        assert_eq!((r.wkc, r.data.as_slice()), (3, &[0x02u8, 0x10][..]));
        let r = exec(&mut esc, &mut dev, Command::Brw, 0, 0x0010, &[0x00, 0x20]);
        assert_eq!(
            (r.wkc, r.data.as_slice()),
            (3, &[0x03u8, 0x30][..]),
            "OR of old"
        );
        assert_eq!(esc.station_address(), 0x2000, "received data stored");
    }

    #[test]
    fn broadcast_read_ors() {
        let (mut esc, mut dev) = slave();
        let r = exec(&mut esc, &mut dev, Command::Brd, 5, 0x0000, &[0xF0, 0x00]);
        assert_eq!(
            (r.adp, r.wkc, r.data.as_slice()),
            (6, 1, &[0xF4u8, 0x01][..])
        );
    }

    #[test]
    fn rmw_reads_when_addressed_and_writes_otherwise() {
        let (mut esc, mut dev) = slave();
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0010, &[0x01, 0x10]);
        let r = exec(&mut esc, &mut dev, Command::Frmw, 0x1001, 0x0010, &[0; 2]);
        assert_eq!((r.wkc, r.data.as_slice()), (1, &[0x01u8, 0x10][..]));
        let r = exec(
            &mut esc,
            &mut dev,
            Command::Frmw,
            0x1002,
            0x0010,
            &[0x05, 0x10],
        );
        assert_eq!(r.wkc, 1);
        assert_eq!(esc.station_address(), 0x1005);
        let r = exec(
            &mut esc,
            &mut dev,
            Command::Armw,
            0xFFFF,
            0x0010,
            &[0x06, 0x10],
        );
        assert_eq!((r.wkc, r.adp), (1, 0));
        assert_eq!(esc.station_address(), 0x1006);
    }

    #[test]
    fn nop_and_unknown_do_nothing() {
        let (mut esc, mut dev) = slave();
        for cmd in [Command::Nop, Command::Unknown(0x20)] {
            let r = exec(&mut esc, &mut dev, cmd, 0, 0x0000, &[0; 2]);
            assert_eq!((r.adp, r.wkc, r.data.as_slice()), (0, 0, &[0u8, 0][..]));
        }
    }

    #[test]
    fn irq_carries_masked_ecat_events() {
        let (mut esc, mut dev) = slave();
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0200, &[0x08, 0x00]);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0120, &[0x05, 0x00]);
        let r = exec(&mut esc, &mut dev, Command::Nop, 0, 0, &[]);
        assert_eq!(r.irq, 0x0008, "AL status change (refusal) pending");
        exec(&mut esc, &mut dev, Command::Aprd, 0, 0x0130, &[0; 2]);
        assert_eq!(exec(&mut esc, &mut dev, Command::Nop, 0, 0, &[]).irq, 0);
    }
}
