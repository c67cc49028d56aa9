//! Frames on the wire: what each carried, when it left, and who waits for it.
//!
//! The bus keeps a fixed set of frame records, allocated when it starts: one per acyclic
//! frame allowed in flight plus one for the cyclic frame. A record is reused for frame after
//! frame, so keeping track of a frame never allocates.

use std::io;
use std::time::Instant;

use crate::wire::command::{AddressingMode, Command};
use crate::wire::datagram::OVERHEAD;
use crate::wire::ethernet::MAX_FRAME_LEN;

use super::config::FRAME_HEADERS_LEN;
use super::queue::Queued;

/// The most datagrams one frame can carry: all of them without data.
pub(crate) const MAX_DATAGRAMS_PER_FRAME: usize = (MAX_FRAME_LEN - FRAME_HEADERS_LEN) / OVERHEAD;

/// What one datagram of a frame looked like when it was sent, to recognise its reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct SentDatagram {
    pub index: u8,
    pub command: Command,
    /// The raw address as sent.
    pub address: u32,
    pub len: u16,
    /// Offset of the datagram from the start of the Ethernet frame.
    pub offset: usize,
}

impl SentDatagram {
    /// Whether a returned datagram's address fits this one. Slaves increment ADP of
    /// position and broadcast commands as the frame passes, so only ADO can be compared
    /// there; node and logical addresses come back unchanged.
    pub fn address_matches(&self, returned: u32) -> bool {
        match self.command.addressing() {
            AddressingMode::Position | AddressingMode::Broadcast => {
                self.address >> 16 == returned >> 16
            }
            AddressingMode::Node | AddressingMode::Logical | AddressingMode::None => {
                self.address == returned
            }
        }
    }
}

/// Whose frame a record holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RecordKind {
    /// Datagrams of callers, retried when lost.
    Acyclic,
    /// The cyclic task's frame, never retried (the next cycle carries newer data).
    Cyclic,
}

/// One frame on the wire.
#[derive(Debug)]
pub(crate) struct FrameRecord {
    pub kind: RecordKind,
    /// A frame is on the wire under this record.
    pub active: bool,
    pub sent_at: Instant,
    pub deadline: Instant,
    /// How many times the frame was sent.
    pub attempts: u32,
    /// Set if the link refused the last send; reported if the frame is then given up.
    pub send_error: Option<io::ErrorKind>,
    /// The datagrams, in frame order.
    pub datagrams: Vec<SentDatagram>,
    /// For acyclic frames, the callers' datagrams, aligned with `datagrams`.
    pub entries: Vec<Queued>,
}

impl FrameRecord {
    pub fn new(kind: RecordKind, now: Instant) -> FrameRecord {
        let entries = match kind {
            RecordKind::Acyclic => MAX_DATAGRAMS_PER_FRAME,
            RecordKind::Cyclic => 0,
        };
        FrameRecord {
            kind,
            active: false,
            sent_at: now,
            deadline: now,
            attempts: 0,
            send_error: None,
            datagrams: Vec::with_capacity(MAX_DATAGRAMS_PER_FRAME),
            entries: Vec::with_capacity(entries),
        }
    }

    /// Marks the record free again (its datagram lists must already be empty or are
    /// emptied here, keeping their memory).
    pub fn clear(&mut self) {
        self.active = false;
        self.attempts = 0;
        self.send_error = None;
        self.datagrams.clear();
        self.entries.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::command::DatagramAddress;

    fn sent(command: Command, address: DatagramAddress) -> SentDatagram {
        SentDatagram {
            index: 0,
            command,
            address: address.to_raw(),
            len: 2,
            offset: 16,
        }
    }

    #[test]
    fn incremented_adp_still_matches_but_another_ado_does_not() {
        let aprd = sent(Command::Aprd, DatagramAddress::position(2, 0x0130));
        let returned = DatagramAddress::Position {
            adp: 0,
            ado: 0x0130,
        };
        assert!(aprd.address_matches(returned.to_raw()));
        assert!(!aprd.address_matches(DatagramAddress::position(2, 0x0132).to_raw()));
        let fprd = sent(
            Command::Fprd,
            DatagramAddress::Node {
                station: 0x1001,
                ado: 0x0130,
            },
        );
        assert!(fprd.address_matches(fprd.address));
        assert!(!fprd.address_matches(fprd.address + 1));
        let lrw = sent(Command::Lrw, DatagramAddress::Logical(0x1_0000));
        assert!(!lrw.address_matches(0x1_0001));
    }

    #[test]
    fn the_largest_frame_holds_124_empty_datagrams() {
        assert_eq!(MAX_DATAGRAMS_PER_FRAME, 124);
    }
}
