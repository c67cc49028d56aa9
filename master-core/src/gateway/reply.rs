//! Reply datagrams: a mailbox message wrapped in the ETG.8200 EtherCAT header, its address
//! field set to the address the client asked (the slave writes its own, or none), in the
//! layout the request came in (`compat`).

use crate::mailbox::RawReply;
use crate::wire::Emit;
use crate::wire::gateway::GatewayRepr;
use crate::wire::mailbox::{MailboxHeader, MailboxType};

use super::compat::{self, Layout};

/// The datagram for a message from a slave going back to a client that used `address`;
/// `None` if it is too long for ETG.8200.
pub(crate) fn from_slave(address: u16, message: &RawReply, layout: Layout) -> Option<Vec<u8>> {
    let header = *message.header();
    let data = message.data();
    match layout {
        Layout::Standard => encode(MailboxHeader { address, ..header }, data),
        Layout::Compat(c) => compat::encode(address, header.mailbox_type, data, c),
    }
}

/// The datagram for a reply the gateway makes (the master's dictionary, an error answer).
pub(crate) fn made(
    address: u16,
    mailbox_type: MailboxType,
    counter: u8,
    data: &[u8],
    layout: Layout,
) -> Option<Vec<u8>> {
    if let Layout::Compat(c) = layout {
        return compat::encode(address, mailbox_type, data, c);
    }
    let header = MailboxHeader {
        length: u16::try_from(data.len()).ok()?,
        address,
        channel: 0,
        priority: 0,
        mailbox_type,
        counter,
    };
    encode(header, data)
}

fn encode(header: MailboxHeader, data: &[u8]) -> Option<Vec<u8>> {
    let repr = GatewayRepr { header, data };
    repr.to_vec().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slave_reply_gets_the_client_address_and_keeps_its_counter() {
        // spec-notes §gateway: the slave's reply to the TwinSAFE Loader, address rewritten.
        let message = [
            0x0a, 0x00, 0xe9, 0x03, 0x00, 0x13, 0x00, 0x30, 0x43, 0x80, 0xf9, 0x02, 0xea, 0x82,
            0x1e, 0x00,
        ];
        let reply = RawReply::parse(&message).unwrap();
        let datagram = from_slave(0x8001, &reply, Layout::Standard).unwrap();
        assert_eq!(datagram[..2], [0x10, 0x50]);
        assert_eq!(datagram[4..6], [0x01, 0x80]);
        assert_eq!(datagram[7], 0x13);
        assert_eq!(datagram[8..], message[6..]);
        assert_eq!(RawReply::parse(&message[..5]), None);
    }
}
