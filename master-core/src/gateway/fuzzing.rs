//! The gateway's own parsing of a datagram, without sockets or slaves, for the fuzz targets
//! `gateway_service` and `gateway_tcp` (fuzz/) and the corpus replay test.
//!
//! Beyond what the wire codec checks, the service reads into the protocol headers:
//! the compatibility layout's translation, tolerance rewrites of short SDO requests, what a message makes the slave do and which
//! transfer it leaves open, its error answers, and the reply datagrams. All of it runs here
//! on the fuzzer's bytes — the request also stands in for a slave's reply — and must never
//! panic.

use std::pin::pin;
use std::task::{Context, Poll, Waker};

use crate::mailbox::RawReply;
use crate::wire::frame::{self, Frame, FrameType};
use crate::wire::gateway::{GatewayMessage, GatewayRepr};
use crate::wire::mailbox::MailboxType;

use super::answer::{Fault, answer};
use super::ask::Ask;
use super::compat::{self, Layout};
use super::normalize;
use super::reply;
use super::tcp::{self, MAX_MESSAGE, Stop};
use super::transfer::{Expect, Sizes, Transfer};

const FAULTS: [Fault; 9] = [
    Fault::UnknownAddress,
    Fault::Unsupported,
    Fault::NotRunning,
    Fault::Timeout,
    Fault::Busy,
    Fault::Oversized,
    Fault::Denied,
    Fault::NotBroadcast,
    Fault::Other,
];

const TRANSFERS: [Option<Transfer>; 6] = [
    None,
    Some(Transfer::Sdo),
    Some(Transfer::FoeRead { last: false }),
    Some(Transfer::FoeRead { last: true }),
    Some(Transfer::FoeWrite),
    Some(Transfer::SoeWrite),
];

/// Runs every parsing step of the service on one datagram. Returns whether it was a
/// well-formed gateway message.
#[doc(hidden)]
pub fn request(datagram: &[u8]) -> bool {
    let Ok(message) = GatewayMessage::new_checked(datagram) else {
        return false;
    };
    let Ok(repr) = GatewayRepr::parse(&message) else {
        return false;
    };
    let (ty, data, layout) = match compat::request(&repr, compat::type_byte(&message)) {
        None => (
            repr.header.mailbox_type,
            repr.data.to_vec(),
            Layout::Standard,
        ),
        Some(Ok(t)) => (t.header.mailbox_type, t.data, Layout::Compat(t.compat)),
        // Well formed as a gateway message; its protocol data are refused (the service
        // counts it as malformed).
        Some(Err(())) => return true,
    };
    let data = match ty {
        MailboxType::Coe => normalize::coe_request(&data).into_owned(),
        _ => data,
    };
    let ask = Ask::read(ty, &data);
    let _ = ask.is_write();
    let _ = ask.is_audited();
    let _ = ask.object();
    let _ = ask.broadcastable();
    // The slave's mailbox sizes, from the bytes themselves (any size goes).
    let sizes = Sizes {
        write: usize::from(repr.header.length),
        read: usize::from(repr.header.address),
    };
    for transfer in TRANSFERS {
        if let Expect::Replies(follows) = ask.expect(transfer) {
            let _ = follows(&data);
            let _ = follows(repr.data);
        }
        let _ = ask.after(Some((ty, repr.data)), transfer, sizes);
        let _ = ask.after(None, transfer, sizes);
    }
    for fault in FAULTS {
        let answers = [answer(&ask, fault), compat::answer(&ask, fault)];
        for (reply_ty, reply_data) in answers.into_iter().flatten() {
            let _ = reply::made(
                repr.header.address,
                reply_ty,
                repr.header.counter,
                &reply_data,
                layout,
            );
        }
    }
    if let Some(slave_reply) = RawReply::parse(message.mailbox_bytes()) {
        let _ = reply::from_slave(repr.header.address, &slave_reply, layout);
        // A slave's reply of any type in the compatibility layout.
        let _ = reply::from_slave(
            repr.header.address,
            &slave_reply,
            Layout::Compat(compat::Compat {
                soe_element: repr.header.counter,
            }),
        );
    }
    true
}

/// Splits a TCP byte stream into gateway messages with the connection's own reader and
/// runs [`request`] on each, until the stream ends or the connection would be closed.
/// Returns the messages read. Panics if a message read is not exactly one EtherCAT header
/// and the mailbox it announces, or if a stream that ends on a message boundary is taken
/// for a broken one.
#[doc(hidden)]
pub fn tcp_stream(stream: &[u8]) -> usize {
    let mut reader = stream;
    let mut buf = vec![0u8; MAX_MESSAGE];
    let mut count = 0;
    loop {
        let consumed = stream.len() - reader.len();
        // A read from a byte slice never waits: one poll finishes it.
        let read = {
            let mut read = pin!(tcp::read_message(&mut reader, &mut buf));
            match read.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
                Poll::Ready(result) => result,
                Poll::Pending => panic!("a read from memory is pending"),
            }
        };
        match read {
            Ok(len) => {
                let message = &buf[..len];
                assert_eq!(message, &stream[consumed..consumed + len], "bytes read");
                let header = Frame::new_unchecked(message);
                assert_eq!(header.frame_type(), FrameType::Mailbox);
                assert_eq!(len, frame::HEADER_LEN + usize::from(header.length()));
                let _ = request(message);
                count += 1;
            }
            Err(Stop::Closed) => {
                // Only at the end of the stream (possibly in the middle of a message).
                assert!(stream.len() - consumed < MAX_MESSAGE, "closed early");
                return count;
            }
            Err(Stop::Malformed) => return count,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Emit;
    use crate::wire::mailbox::MailboxHeader;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn well_formed_messages_with_any_protocol_data_never_panic(
            ty in 0u8..16,
            address in any::<u16>(),
            counter in 0u8..8,
            data in proptest::collection::vec(any::<u8>(), 0..200),
        ) {
            let repr = GatewayRepr {
                header: MailboxHeader {
                    length: data.len() as u16,
                    address,
                    channel: 0,
                    priority: 0,
                    mailbox_type: MailboxType::from(ty),
                    counter,
                },
                data: &data,
            };
            let datagram = repr.to_vec().unwrap();
            prop_assert!(request(&datagram));
            // The same message twice on a TCP stream, then half of it.
            let mut stream = [&datagram[..], &datagram[..]].concat();
            stream.extend_from_slice(&datagram[..datagram.len() / 2]);
            prop_assert_eq!(tcp_stream(&stream), 2);
            for len in 0..datagram.len() {
                prop_assert!(!request(&datagram[..len]));
            }
        }
    }
}
