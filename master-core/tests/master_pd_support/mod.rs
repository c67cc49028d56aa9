//! Shared by the process-data tests: a link that keeps every frame that came back, and
//! decoders that pick datagrams and SDO writes out of them.
#![allow(dead_code)]

use std::io;
use std::sync::{Arc, Mutex, PoisonError};

use master_core::link::{Link, Wait};
use master_core::wire::coe::{CoeRepr, SdoPayload, SdoRequest};
use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::frame::EthercatFrame;
use master_core::wire::mailbox::{MailboxMessage, MailboxPayload};

/// Frames kept at most (a test that runs longer keeps the first ones).
const KEEP: usize = 200_000;

/// Every frame received through the wrapped link, as it came back from the segment.
#[derive(Clone, Default)]
pub struct Returned(Arc<Mutex<Vec<Vec<u8>>>>);

impl Returned {
    /// A copy of the frames so far.
    pub fn frames(&self) -> Vec<Vec<u8>> {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Forgets the frames so far.
    pub fn clear(&self) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
    }
}

/// A link that records what it receives.
pub struct Recording<L> {
    pub inner: L,
    pub returned: Returned,
}

impl<L: Link> Link for Recording<L> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.inner.send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        let got = self.inner.recv(buf, wait)?;
        if let Some(len) = got {
            let mut frames = self
                .returned
                .0
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            if frames.len() < KEEP {
                frames.push(buf[..len].to_vec());
            }
        }
        Ok(got)
    }
}

/// Every returned datagram as (command, address, data, wkc).
pub fn datagrams(frames: &[Vec<u8>]) -> Vec<(Command, Option<DatagramAddress>, Vec<u8>, u16)> {
    let mut out = Vec::new();
    for frame in frames {
        let Ok(parsed) = EthercatFrame::parse(frame) else {
            continue;
        };
        let Ok(list) = parsed.datagrams() else {
            continue;
        };
        for d in list.flatten() {
            out.push((d.command, d.typed_address(), d.data.to_vec(), d.wkc));
        }
    }
    out
}

/// Datagrams addressed by station `station` at `ado` with command `command`.
pub fn count_node(frames: &[Vec<u8>], command: Command, station: u16, ado: u16) -> usize {
    datagrams(frames)
        .into_iter()
        .filter(|(c, a, ..)| *c == command && *a == Some(DatagramAddress::Node { station, ado }))
        .count()
}

/// The SDO downloads (index, subindex, data) written to `station`'s mailbox at `sm0`
/// that the slave took (working counter 1), in order.
pub fn sdo_downloads(frames: &[Vec<u8>], station: u16, sm0: u16) -> Vec<(u16, u8, Vec<u8>)> {
    datagrams(frames)
        .into_iter()
        .filter(|(c, a, _, wkc)| {
            *c == Command::Fpwr
                && *a == Some(DatagramAddress::Node { station, ado: sm0 })
                && *wkc == 1
        })
        .filter_map(|(_, _, data, _)| {
            let message = MailboxMessage::parse(&data).ok()?;
            match message.payload {
                MailboxPayload::Coe(CoeRepr::SdoRequest(SdoRequest::InitiateDownload {
                    index,
                    subindex,
                    payload: SdoPayload::Expedited(value),
                    ..
                })) => Some((index, subindex, value.to_vec())),
                _ => None,
            }
        })
        .collect()
}
