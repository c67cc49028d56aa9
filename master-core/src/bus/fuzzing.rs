//! The frame matcher without a link, for the fuzz target `frame_matcher` (fuzz/) and the
//! corpus replay test: a frame is put in flight as the bus records it, then a returned frame
//! is matched against it.

use std::time::Instant;

use crate::wire::frame::EthercatFrame;

use super::index::IndexTable;
use super::matching::{Match, match_frame};
use super::record::{FrameRecord, RecordKind, SentDatagram};

/// The frame in flight for `sent` (record 0), or `None` if the bus could not have sent it
/// (not a whole datagram chain).
fn in_flight(sent: &EthercatFrame<'_>) -> Option<(IndexTable, Vec<FrameRecord>)> {
    let mut indices = IndexTable::new();
    let mut record = FrameRecord::new(RecordKind::Acyclic, Instant::now());
    record.active = true;
    for datagram in sent.datagrams().ok()? {
        let datagram = datagram.ok()?;
        // Take indices up to this one and keep only it, as the table hands them out in turn.
        while indices.owner(datagram.index).is_none() {
            let taken = indices.take(0)?;
            if taken != datagram.index {
                indices.release(taken);
            }
        }
        record.datagrams.push(SentDatagram {
            index: datagram.index,
            command: datagram.command,
            address: datagram.address,
            len: u16::try_from(datagram.data.len()).ok()?,
            offset: 0,
        });
    }
    if record.datagrams.is_empty() {
        return None;
    }
    // A second record, not active: nothing may match it.
    let mut idle = FrameRecord::new(RecordKind::Cyclic, Instant::now());
    idle.datagrams = record.datagrams.clone();
    Some((indices, vec![record, idle]))
}

/// Matches frames from `data`: two length bytes (little endian), the frame sent, then the
/// frame returned. Panics if a sent frame does not match itself, or a match is declared
/// for a returned frame whose datagrams differ from the ones sent.
#[doc(hidden)]
pub fn reply(data: &[u8]) {
    let Some((len, rest)) = data.split_first_chunk::<2>() else {
        return;
    };
    let (sent, returned) = rest.split_at(usize::from(u16::from_le_bytes(*len)).min(rest.len()));
    let flight = EthercatFrame::parse(sent).ok().and_then(|f| {
        let flight = in_flight(&f)?;
        assert_eq!(
            match_frame(&f, &flight.0, &flight.1),
            Match::Reply(0),
            "a frame is its own reply"
        );
        Some(flight)
    });
    let Ok(returned) = EthercatFrame::parse(returned) else {
        return;
    };
    let Some((indices, records)) = flight else {
        // Nothing in flight: nothing can match.
        let empty = IndexTable::new();
        assert_ne!(
            match_frame(&returned, &empty, &[]),
            Match::Reply(0),
            "a reply with nothing in flight"
        );
        return;
    };
    match match_frame(&returned, &indices, &records) {
        Match::Reply(id) => {
            assert_eq!(id, 0, "the idle record matched");
            let datagrams: Vec<_> = returned
                .datagrams()
                .expect("a matched frame has datagrams")
                .map(|d| d.expect("a matched frame is whole"))
                .collect();
            let sent = &records[0].datagrams;
            assert_eq!(datagrams.len(), sent.len(), "datagram count");
            for (got, want) in datagrams.iter().zip(sent) {
                assert!(
                    got.index == want.index
                        && got.command == want.command
                        && got.data.len() == usize::from(want.len)
                        && want.address_matches(got.address),
                    "a datagram that differs matched"
                );
            }
        }
        Match::Foreign => {
            let whole = returned.datagrams().is_ok_and(|d| {
                let items: Vec<_> = d.collect();
                !items.is_empty() && items.iter().all(Result::is_ok)
            });
            assert!(!whole, "a whole datagram chain called foreign");
        }
        Match::Stale => {}
    }
}
