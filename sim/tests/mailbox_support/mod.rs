//! A tiny master for the mailbox tests: builds requests with the wire codecs, hands them to a
//! slave's mailbox stack as the ESC would (a complete SM0 buffer), and reads back everything
//! the slave posts, one SM1 message at a time.

#![allow(dead_code)]

use ecat_wire::mailbox::{
    ErrorReply, ErrorReplyRepr, HEADER_LEN, Mailbox, MailboxErrorCode, MailboxHeader, MailboxType,
};
use ecat_wire::register::al::AlState;
use sim::device::{Device, DeviceContext, MailboxStack, Outbox};

/// One slave's mailbox, driven the way the master drives it.
pub struct Bench {
    pub stack: MailboxStack,
    pub ctx: DeviceContext,
    pub outbox: Outbox,
    counter: u8,
    pub address: u16,
}

/// A message the slave posted, parsed with the codec.
#[derive(Debug, Clone)]
pub struct Reply {
    pub header: MailboxHeader,
    pub data: Vec<u8>,
}

impl Reply {
    /// The mailbox error code, if this is a type-0 reply.
    pub fn error_code(&self) -> Option<MailboxErrorCode> {
        if self.header.mailbox_type != MailboxType::Error {
            return None;
        }
        let reply = ErrorReply::new_checked(&self.data[..]).expect("error reply data");
        Some(ErrorReplyRepr::parse(&reply).expect("error reply").detail)
    }
}

/// Parses one posted message; panics (failing the test) if the codec refuses it.
pub fn parse_reply(message: &[u8]) -> Reply {
    let view = Mailbox::new_checked(message).expect("reply parses");
    let header = MailboxHeader::parse(&view).expect("reply header");
    assert_eq!(view.total_len(), message.len(), "no bytes beyond length");
    Reply {
        header,
        data: view.data().to_vec(),
    }
}

impl Bench {
    /// A bench with SM0 = `sm0` and SM1 = `sm1` bytes, in PREOP, station address 1001.
    pub fn new(stack: MailboxStack, sm0: u16, sm1: u16) -> Self {
        Bench {
            stack,
            ctx: DeviceContext {
                station_address: 1001,
                al_state: AlState::PreOp,
                rx_mailbox_size: sm0,
                tx_mailbox_size: sm1,
            },
            // One message: SM1 holds one message at a time.
            outbox: Outbox::new(1),
            counter: 0,
            address: 0,
        }
    }

    /// Builds a request of `mailbox_type` carrying `data`, with the master's next counter.
    pub fn build(&mut self, mailbox_type: MailboxType, data: &[u8]) -> Vec<u8> {
        self.counter = self.counter % 7 + 1;
        let counter = self.counter;
        build_message(mailbox_type, self.address, 0, counter, data)
    }

    /// Sends a request and reads every message the slave posts in answer.
    pub fn request(&mut self, mailbox_type: MailboxType, data: &[u8]) -> Vec<Reply> {
        let message = self.build(mailbox_type, data);
        self.send_padded(&message)
    }

    /// Sends a request expecting exactly one reply, and returns its data.
    pub fn one(&mut self, mailbox_type: MailboxType, data: &[u8]) -> Reply {
        let mut replies = self.request(mailbox_type, data);
        assert_eq!(replies.len(), 1, "expected one reply, got {replies:?}");
        replies.remove(0)
    }

    /// Writes `message` into SM0 as a master does: padded to the full SM0 length.
    pub fn send_padded(&mut self, message: &[u8]) -> Vec<Reply> {
        let mut buffer = message.to_vec();
        let sm0 = usize::from(self.ctx.rx_mailbox_size);
        if buffer.len() < sm0 {
            buffer.resize(sm0, 0);
        }
        self.send_raw(&buffer)
    }

    /// Hands `bytes` to the stack unchanged.
    pub fn send_raw(&mut self, bytes: &[u8]) -> Vec<Reply> {
        self.stack
            .mailbox_received(bytes, &self.ctx, &mut self.outbox);
        self.drain()
    }

    /// Reads SM1 until the slave has nothing more to say.
    pub fn drain(&mut self) -> Vec<Reply> {
        let mut replies = Vec::new();
        loop {
            while let Some(message) = self.outbox.pop() {
                assert!(
                    message.len() <= usize::from(self.ctx.tx_mailbox_size),
                    "message larger than SM1"
                );
                replies.push(parse_reply(&message));
            }
            self.stack.poll(&self.ctx, &mut self.outbox);
            if self.outbox.is_empty() {
                return replies;
            }
        }
    }
}

/// A complete mailbox message built with the codec.
pub fn build_message(
    mailbox_type: MailboxType,
    address: u16,
    channel: u8,
    counter: u8,
    data: &[u8],
) -> Vec<u8> {
    let header = MailboxHeader {
        length: u16::try_from(data.len()).unwrap(),
        address,
        channel,
        priority: 0,
        mailbox_type,
        counter,
    };
    let mut message = vec![0u8; HEADER_LEN + data.len()];
    let mut view = Mailbox::new_unchecked(&mut message[..]);
    header.emit(&mut view).unwrap();
    view.data_mut().copy_from_slice(data);
    message
}
