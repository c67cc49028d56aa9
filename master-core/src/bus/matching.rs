//! Recognising a returned frame as one of ours.
//!
//! Slaves change data, working counters, ADP (for position and broadcast commands), IRQ
//! and the C flag, but never the number, order, command, index, ADO or length of the
//! datagrams in a frame. So a returned frame belongs to the frame in flight under its first
//! datagram's index only if every one of its datagrams matches what that frame carried, in
//! order. Anything else — a late reply to a frame that was already sent again, a duplicate,
//! another master's traffic, a damaged frame — is ignored as a whole, so that no caller is
//! ever handed somebody else's data.

use crate::wire::frame::EthercatFrame;

use super::index::IndexTable;
use super::record::FrameRecord;

/// What a received frame is to us.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Match {
    /// Not an EtherCAT datagram frame, or a malformed one.
    Foreign,
    /// A well-formed datagram frame that matches no frame in flight.
    Stale,
    /// The reply to the frame in flight under this record.
    Reply(u16),
}

/// Finds the frame in flight that `frame` answers.
pub(crate) fn match_frame(
    frame: &EthercatFrame<'_>,
    indices: &IndexTable,
    records: &[FrameRecord],
) -> Match {
    let Ok(datagrams) = frame.datagrams() else {
        return Match::Foreign;
    };
    // The chain must be whole before anything is believed.
    if datagrams.clone().any(|item| item.is_err()) {
        return Match::Foreign;
    }
    let mut datagrams = datagrams.flatten();
    let Some(first) = datagrams.clone().next() else {
        return Match::Foreign;
    };
    let Some(id) = indices.owner(first.index) else {
        return Match::Stale;
    };
    let Some(record) = records.get(usize::from(id)).filter(|r| r.active) else {
        return Match::Stale;
    };
    for sent in &record.datagrams {
        let Some(returned) = datagrams.next() else {
            return Match::Stale;
        };
        let same = returned.index == sent.index
            && returned.command == sent.command
            && returned.data.len() == usize::from(sent.len)
            && sent.address_matches(returned.address);
        if !same {
            return Match::Stale;
        }
    }
    if datagrams.next().is_some() {
        return Match::Stale;
    }
    Match::Reply(id)
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::*;
    use crate::bus::record::{RecordKind, SentDatagram};
    use crate::wire::command::{Command, DatagramAddress};
    use crate::wire::datagram::DatagramRepr;
    use crate::wire::frame::FrameBuilder;

    const SOURCE: [u8; 6] = [2, 0, 0, 0, 0, 1];

    /// Builds a frame of `(command, index, address, len)` datagrams.
    fn frame(datagrams: &[(Command, u8, DatagramAddress, usize)]) -> Vec<u8> {
        let mut buf = vec![0u8; 1514];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        let zeros = [0u8; 64];
        for &(command, index, address, len) in datagrams {
            builder
                .push(&DatagramRepr::request(
                    command,
                    index,
                    address,
                    &zeros[..len],
                ))
                .unwrap();
        }
        let len = builder.finish(SOURCE).unwrap();
        buf.truncate(len);
        buf
    }

    /// One record (id 0) in flight with what `bytes` carries.
    fn in_flight(bytes: &[u8]) -> (IndexTable, Vec<FrameRecord>) {
        let parsed = EthercatFrame::parse(bytes).unwrap();
        let mut indices = IndexTable::new();
        let mut record = FrameRecord::new(RecordKind::Cyclic, Instant::now());
        record.active = true;
        for datagram in parsed.datagrams().unwrap() {
            let datagram = datagram.unwrap();
            // Take indices up to this one, keep only it.
            while indices.owner(datagram.index).is_none() {
                let taken = indices.take(0).unwrap();
                if taken != datagram.index {
                    indices.release(taken);
                }
            }
            record.datagrams.push(SentDatagram {
                index: datagram.index,
                command: datagram.command,
                address: datagram.address,
                len: datagram.data.len() as u16,
                offset: 0,
            });
        }
        (indices, vec![record])
    }

    fn node(ado: u16) -> DatagramAddress {
        DatagramAddress::Node {
            station: 0x1001,
            ado,
        }
    }

    #[test]
    fn the_reply_matches_even_with_adp_incremented() {
        let sent = frame(&[
            (Command::Fprd, 3, node(0x130), 2),
            (Command::Brd, 4, DatagramAddress::broadcast(0), 2),
        ]);
        let (indices, records) = in_flight(&sent);
        let reply = frame(&[
            (Command::Fprd, 3, node(0x130), 2),
            (
                Command::Brd,
                4,
                DatagramAddress::Broadcast { adp: 3, ado: 0 },
                2,
            ),
        ]);
        let parsed = EthercatFrame::parse(&reply).unwrap();
        assert_eq!(match_frame(&parsed, &indices, &records), Match::Reply(0));
    }

    #[test]
    fn anything_that_differs_is_stale_and_garbage_is_foreign() {
        let sent = frame(&[
            (Command::Fprd, 3, node(0x130), 2),
            (Command::Fprd, 4, node(0x132), 2),
        ]);
        let (indices, records) = in_flight(&sent);
        let check = |datagrams: &[(Command, u8, DatagramAddress, usize)]| {
            let bytes = frame(datagrams);
            match_frame(&EthercatFrame::parse(&bytes).unwrap(), &indices, &records)
        };
        // A datagram missing, one too many, another length, command, address or index.
        assert_eq!(check(&[(Command::Fprd, 3, node(0x130), 2)]), Match::Stale);
        assert_eq!(
            check(&[
                (Command::Fprd, 3, node(0x130), 2),
                (Command::Fprd, 4, node(0x132), 2),
                (Command::Fprd, 5, node(0x134), 2),
            ]),
            Match::Stale
        );
        for changed in [
            (Command::Fprd, 4, node(0x132), 4),
            (Command::Fpwr, 4, node(0x132), 2),
            (Command::Fprd, 4, node(0x134), 2),
            (Command::Fprd, 9, node(0x132), 2),
        ] {
            assert_eq!(
                check(&[(Command::Fprd, 3, node(0x130), 2), changed]),
                Match::Stale
            );
        }
        // An index that is not in flight at all.
        assert_eq!(check(&[(Command::Fprd, 7, node(0x130), 2)]), Match::Stale);
        // A chain cut short.
        let mut cut = sent.clone();
        // M on the last datagram (its flags word is at 30 + 6): more is announced than
        // the EtherCAT length holds.
        cut[37] |= 0x80;
        let parsed = EthercatFrame::parse(&cut).unwrap();
        assert_eq!(match_frame(&parsed, &indices, &records), Match::Foreign);
    }
}
