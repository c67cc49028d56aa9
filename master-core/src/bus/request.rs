//! What a caller asks of the bus, and what it gets back.

use std::time::{Duration, Instant};

use crate::wire::command::{Command, DatagramAddress};

use super::data::DatagramData;
use super::stamp::Stamp;

/// What working counter a caller expects (spec-notes §commands lists what each command adds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WkcCheck {
    /// Any working counter is fine; the caller looks at it itself (for example a mailbox
    /// poll, where 0 just means "empty").
    #[default]
    Ignore,
    /// Exactly this working counter, or the datagram fails with
    /// [`BusError::WorkingCounter`](super::BusError::WorkingCounter).
    Exact(u16),
}

impl WkcCheck {
    /// Whether `wkc` passes this check.
    pub fn accepts(self, wkc: u16) -> bool {
        match self {
            WkcCheck::Ignore => true,
            WkcCheck::Exact(expected) => wkc == expected,
        }
    }
}

/// One datagram to send: command, address, data, and the working counter to expect.
///
/// For reads, `data` is `len` zero bytes that the slaves fill in (the constructors for read
/// commands make them). For read-write commands it is what is written, and the reply holds
/// what was read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatagramRequest {
    /// The command.
    pub command: Command,
    /// The address; its addressing mode must be the command's.
    pub address: DatagramAddress,
    /// The data sent.
    pub data: DatagramData,
    /// The working counter to expect.
    pub wkc: WkcCheck,
}

impl DatagramRequest {
    /// A request with any command and data; the working counter is not checked.
    pub fn new(
        command: Command,
        address: DatagramAddress,
        data: impl Into<DatagramData>,
    ) -> DatagramRequest {
        DatagramRequest {
            command,
            address,
            data: data.into(),
            wkc: WkcCheck::Ignore,
        }
    }

    /// A request carrying `len` zero bytes, for commands that read.
    pub fn read(command: Command, address: DatagramAddress, len: usize) -> DatagramRequest {
        DatagramRequest::new(command, address, DatagramData::zeroed(len))
    }

    /// The same request, failing unless the working counter is exactly `wkc`.
    pub fn expect_wkc(self, wkc: u16) -> DatagramRequest {
        DatagramRequest {
            wkc: WkcCheck::Exact(wkc),
            ..self
        }
    }

    /// APRD: read `len` bytes at `ado` of the slave at ring `position`.
    pub fn aprd(position: u16, ado: u16, len: usize) -> DatagramRequest {
        DatagramRequest::read(Command::Aprd, DatagramAddress::position(position, ado), len)
    }

    /// APWR: write `data` at `ado` of the slave at ring `position`.
    pub fn apwr(position: u16, ado: u16, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(
            Command::Apwr,
            DatagramAddress::position(position, ado),
            data,
        )
    }

    /// APRW: exchange `data` with the memory at `ado` of the slave at ring `position`.
    pub fn aprw(position: u16, ado: u16, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(
            Command::Aprw,
            DatagramAddress::position(position, ado),
            data,
        )
    }

    /// FPRD: read `len` bytes at `ado` of the slave with station address `station`.
    pub fn fprd(station: u16, ado: u16, len: usize) -> DatagramRequest {
        DatagramRequest::read(Command::Fprd, DatagramAddress::Node { station, ado }, len)
    }

    /// FPWR: write `data` at `ado` of the slave with station address `station`.
    pub fn fpwr(station: u16, ado: u16, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(Command::Fpwr, DatagramAddress::Node { station, ado }, data)
    }

    /// FPRW: exchange `data` with the memory at `ado` of the slave `station`.
    pub fn fprw(station: u16, ado: u16, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(Command::Fprw, DatagramAddress::Node { station, ado }, data)
    }

    /// BRD: OR `len` bytes at `ado` of every slave; the working counter counts them.
    pub fn brd(ado: u16, len: usize) -> DatagramRequest {
        DatagramRequest::read(Command::Brd, DatagramAddress::broadcast(ado), len)
    }

    /// BWR: write `data` at `ado` of every slave.
    pub fn bwr(ado: u16, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(Command::Bwr, DatagramAddress::broadcast(ado), data)
    }

    /// BRW: every slave ORs its memory at `ado` into the data and writes what it received.
    pub fn brw(ado: u16, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(Command::Brw, DatagramAddress::broadcast(ado), data)
    }

    /// LRD: read `len` bytes of logical memory at `address`.
    pub fn lrd(address: u32, len: usize) -> DatagramRequest {
        DatagramRequest::read(Command::Lrd, DatagramAddress::Logical(address), len)
    }

    /// LWR: write `data` to logical memory at `address`.
    pub fn lwr(address: u32, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(Command::Lwr, DatagramAddress::Logical(address), data)
    }

    /// LRW: write `data` to and read inputs from logical memory at `address`.
    pub fn lrw(address: u32, data: impl Into<DatagramData>) -> DatagramRequest {
        DatagramRequest::new(Command::Lrw, DatagramAddress::Logical(address), data)
    }

    /// ARMW: the slave at `position` reads `len` bytes at `ado`, all others write them (DC
    /// reference time distribution).
    pub fn armw(position: u16, ado: u16, len: usize) -> DatagramRequest {
        DatagramRequest::read(Command::Armw, DatagramAddress::position(position, ado), len)
    }

    /// FRMW: the slave `station` reads `len` bytes at `ado`, all others write them.
    pub fn frmw(station: u16, ado: u16, len: usize) -> DatagramRequest {
        DatagramRequest::read(Command::Frmw, DatagramAddress::Node { station, ado }, len)
    }
}

/// A returned datagram.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatagramResponse {
    /// The data as it came back (as long as the request's data).
    pub data: DatagramData,
    /// The working counter.
    pub wkc: u16,
    /// The address as it came back. Slaves increment ADP for position and broadcast
    /// commands, so a returned BRD's ADP counts the slaves it passed.
    pub address: DatagramAddress,
    /// The IRQ word: event requests ORed in by the slaves.
    pub irq: u16,
    /// When the frame that brought this response left the master. A mailbox learns from
    /// it when a slave's answer was there: the read that found it reached the slave on
    /// its way out, and the time it came back adds nothing but the way home.
    pub sent_at: Stamp,
    /// How long before `sent_at` the datagram first left, in µs (saturating at 65 ms): not
    /// 0 only for a poll that was sent again while it found nothing
    /// ([`BusHandle::submit_once_polling`](super::BusHandle::submit_once_polling)). In µs
    /// rather than a second moment, so that an error carrying a response stays small.
    pub polled_us: u16,
}

impl DatagramResponse {
    /// When the datagram first left the master (see [`DatagramResponse::polled_us`]).
    pub fn first_sent_at(&self) -> Instant {
        let sent = self.sent_at.instant();
        sent.checked_sub(Duration::from_micros(u64::from(self.polled_us)))
            .unwrap_or(sent)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_pick_command_address_and_data() {
        let read = DatagramRequest::fprd(0x1001, 0x0130, 6);
        assert_eq!(read.command, Command::Fprd);
        assert_eq!(
            read.address,
            DatagramAddress::Node {
                station: 0x1001,
                ado: 0x0130
            }
        );
        assert_eq!(read.data.as_slice(), &[0; 6]);
        assert_eq!(read.wkc, WkcCheck::Ignore);
        let write = DatagramRequest::apwr(1, 0x0010, [0x02, 0x10]).expect_wkc(1);
        assert_eq!(write.address.ring_position(), Some(1));
        assert_eq!(write.data.as_slice(), &[0x02, 0x10]);
        assert_eq!(write.wkc, WkcCheck::Exact(1));
        assert_eq!(DatagramRequest::lrw(0x1_0000, vec![1; 40]).data.len(), 40);
        assert_eq!(DatagramRequest::brd(0, 2).command, Command::Brd);
    }

    #[test]
    fn wkc_checks() {
        assert!(WkcCheck::Ignore.accepts(0));
        assert!(WkcCheck::Exact(3).accepts(3));
        assert!(!WkcCheck::Exact(3).accepts(2));
    }
}
