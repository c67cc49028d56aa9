//! The compatibility layout (docs/gateway.md, "Compatibility layout"): the UDP clients
//! printed in the manual of the gateway this one replaces put the mailbox type in bits 7:4 of
//! the mailbox header's type byte, with bits 3:0 zero, and number the protocols their own way
//! (2 EoE, 3 CoE, 4 SoE, 5 FoE, 15 VoE). ETG.1000.4 §5.6 (mailbox header, Table 29) and
//! ETG.8200 put the type in bits 3:0 (2 EoE, 3 CoE, 4 FoE, 5 SoE, 15 VoE) and the counter in
//! bits 6:4. A request never carries type 0 (ERR) in bits 3:0, so a type byte with a zero low
//! nibble and a known code in the high one can only be the other layout: the gateway tells
//! the two apart by that byte alone, per message.
//!
//! Those clients also lay out SoE and FoE differently (`soe`, `foe`); CoE, VoE and EoE data
//! are the standard's. A request in this layout is translated into the standard message
//! ([`request`]) before anything else looks at it, and every reply to it, the gateway's own
//! error answers included (`errors`), is translated back ([`encode`]), so routing, sessions,
//! retries and roles see standard messages only.

mod errors;
mod foe;
mod soe;

use crate::wire::Emit;
use crate::wire::gateway::{ECAT_HEADER_LEN, GatewayMessage, GatewayRepr};
use crate::wire::mailbox::{MailboxHeader, MailboxType};

pub(crate) use errors::answer;

/// Byte of the mailbox header that holds type and counter (ETG.1000.4 Table 29).
const TYPE_BYTE: usize = 5;

/// How a request was laid out; its replies go back the same way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Layout {
    /// ETG.1000.4 / ETG.8200.
    Standard,
    /// The manual's clients' layout.
    Compat(Compat),
}

/// What the reply of a compatibility-layout request needs from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Compat {
    /// SoE: the client's byte 1 (drive << 3 | element number), returned in the reply.
    pub soe_element: u8,
}

/// The manual's code of a mailbox type (the value in bits 7:4).
fn code(ty: MailboxType) -> Option<u8> {
    match ty {
        MailboxType::Error => Some(0),
        MailboxType::Eoe => Some(2),
        MailboxType::Coe => Some(3),
        MailboxType::Soe => Some(4),
        MailboxType::Foe => Some(5),
        MailboxType::Voe => Some(15),
        _ => None,
    }
}

/// The mailbox type of a request's type byte in the compatibility layout, `None` if the
/// byte is a standard one (low nibble not zero) or names no protocol.
pub(crate) fn detect(type_byte: u8) -> Option<MailboxType> {
    if type_byte & 0x0F != 0 {
        return None;
    }
    match type_byte >> 4 {
        2 => Some(MailboxType::Eoe),
        3 => Some(MailboxType::Coe),
        4 => Some(MailboxType::Soe),
        5 => Some(MailboxType::Foe),
        15 => Some(MailboxType::Voe),
        _ => None,
    }
}

/// A parsed request in the compatibility layout, as the standard message it stands for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Translated {
    /// The header with the standard type and counter 0 (the layout has no counter).
    pub header: MailboxHeader,
    /// The standard mailbox data.
    pub data: Vec<u8>,
    /// What its replies need.
    pub compat: Compat,
}

/// The standard form of `repr` if it is in the compatibility layout (`type_byte` is the raw
/// type byte of its mailbox header); `Some(Err(()))` if it is in that layout but its protocol
/// data cannot be translated (malformed), `None` if it is a standard message.
pub(crate) fn request(repr: &GatewayRepr<'_>, type_byte: u8) -> Option<Result<Translated, ()>> {
    let ty = detect(type_byte)?;
    let translated = match ty {
        MailboxType::Soe => {
            soe::to_standard(repr.data).map(|(data, soe_element)| (data, Compat { soe_element }))
        }
        MailboxType::Foe => foe::to_standard(repr.data).map(|data| (data, Compat::default())),
        _ => Some((repr.data.to_vec(), Compat::default())),
    };
    Some(
        translated
            .and_then(|(data, compat)| {
                let length = u16::try_from(data.len()).ok()?;
                Some(Translated {
                    header: MailboxHeader {
                        length,
                        mailbox_type: ty,
                        counter: 0,
                        ..repr.header
                    },
                    data,
                    compat,
                })
            })
            .ok_or(()),
    )
}

/// The raw type byte of a gateway message's mailbox header (one that passed
/// [`GatewayMessage::check_len`]).
pub(crate) fn type_byte<T: AsRef<[u8]>>(message: &GatewayMessage<T>) -> u8 {
    message.mailbox_bytes().get(TYPE_BYTE).copied().unwrap_or(0)
}

/// The datagram for a reply of `ty` with standard mailbox data `data` to a request in the
/// compatibility layout that used `address`: the manual's type code in bits 7:4, no counter,
/// SoE and FoE data in its layout. `None` if the type has no code or the result is too long.
pub(crate) fn encode(
    address: u16,
    ty: MailboxType,
    data: &[u8],
    compat: Compat,
) -> Option<Vec<u8>> {
    let code = code(ty)?;
    let data = match ty {
        MailboxType::Soe => soe::to_compat(data, compat.soe_element)?,
        MailboxType::Foe => foe::to_compat(data)?,
        _ => data.to_vec(),
    };
    // Emitted as a standard message of type 0, counter 0 (type byte 0x00), then the byte is
    // set to the manual's code: the header codec rightly refuses a type above 15.
    let header = MailboxHeader {
        length: u16::try_from(data.len()).ok()?,
        address,
        channel: 0,
        priority: 0,
        mailbox_type: MailboxType::Error,
        counter: 0,
    };
    let repr = GatewayRepr {
        header,
        data: &data,
    };
    let mut out = repr.to_vec().ok()?;
    *out.get_mut(ECAT_HEADER_LEN + TYPE_BYTE)? = code << 4;
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_zero_low_nibble_with_a_known_code_is_the_compatibility_layout() {
        assert_eq!(detect(0x30), Some(MailboxType::Coe));
        assert_eq!(detect(0x40), Some(MailboxType::Soe));
        assert_eq!(detect(0x50), Some(MailboxType::Foe));
        assert_eq!(detect(0xF0), Some(MailboxType::Voe));
        assert_eq!(detect(0x20), Some(MailboxType::Eoe));
        // Standard CoE with counter 3, FoE with counter 5: low nibble set.
        assert_eq!(detect(0x33), None);
        assert_eq!(detect(0x54), None);
        // Type 0 with counter 0 or 1 (a mailbox error, never a request): no protocol code.
        assert_eq!(detect(0x00), None);
        assert_eq!(detect(0x10), None);
    }

    #[test]
    fn a_reply_carries_the_code_in_the_high_nibble_and_no_counter() {
        let datagram = encode(0x03E9, MailboxType::Coe, &[1, 2, 3], Compat::default()).unwrap();
        assert_eq!(datagram, [0x09, 0x50, 3, 0, 0xE9, 0x03, 0, 0x30, 1, 2, 3]);
        let voe = encode(1, MailboxType::Voe, &[0; 6], Compat::default()).unwrap();
        assert_eq!(voe[7], 0xF0);
        let error = encode(1, MailboxType::Error, &[1, 0, 2, 0], Compat::default()).unwrap();
        assert_eq!(error[7], 0x00);
    }
}
