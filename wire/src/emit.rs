//! [`Emit`]: one way to write any representation into bytes, so callers need not repeat
//! "allocate `buffer_len()` bytes, wrap them in the view, emit".
//!
//! The representations keep their own `buffer_len`/`emit` (the view-level contract of the
//! [module documentation](crate)); this trait is implemented for each of them here,
//! over a plain byte slice.

use crate::coe::info::{SdoInfoFrame, SdoInfoRepr};
use crate::coe::sdo::SdoFrame;
use crate::coe::sdo_request::SdoRequest;
use crate::coe::sdo_response::SdoResponse;
use crate::coe::{CoeFrame, CoeHeaderRepr, CoeRepr, EmergencyFrame, EmergencyRepr};
use crate::datagram::{Datagram, DatagramRepr};
use crate::eoe::fragment::FragmentRepr;
use crate::eoe::{EoePacket, EoeRepr};
use crate::error::{Result, room};
use crate::ethernet::{EthernetFrame, EthernetRepr};
use crate::foe::{FoePacket, FoeRepr};
use crate::frame::{Frame, FrameHeader};
use crate::gateway::{GatewayMessage, GatewayRepr};
use crate::mailbox::error_reply::{ErrorReply, ErrorReplyRepr};
use crate::mailbox::{Mailbox, MailboxHeader, MailboxMessage};
use crate::register::{
    AlStatusBlock, AlStatusBlockRepr, EepromRequest, EepromRequestRepr, ErrorCounters,
    ErrorCountersRepr, EscInfo, EscInfoRepr, Fmmu, FmmuRepr, SyncManager, SyncManagerRepr,
};
use crate::sii::dc::DcCategoryRepr;
use crate::sii::fmmu::FmmuCategoryRepr;
use crate::sii::general::GeneralRepr;
use crate::sii::pdo::PdoCategoryRepr;
use crate::sii::strings::StringsRepr;
use crate::sii::syncm::SyncmCategoryRepr;
use crate::sii::{Category, CategoryRepr, SiiFixed, SiiFixedRepr};
use crate::soe::{SoePacket, SoeRepr};
use crate::voe::{VoePacket, VoeRepr};

/// A representation that can be written as bytes.
pub trait Emit {
    /// The number of bytes the representation takes (its `buffer_len`).
    fn wire_len(&self) -> usize;

    /// Writes the representation at the start of `buffer` and returns the bytes written
    /// ([`wire_len`](Self::wire_len)).
    ///
    /// Errors: a buffer shorter than `wire_len()` ([`WireError::BufferTooSmall`](crate::WireError::BufferTooSmall));
    /// out-of-range field values, as the representation's own `emit` refuses them.
    fn emit_into(&self, buffer: &mut [u8]) -> Result<usize>;

    /// The representation as a new vector of exactly `wire_len()` bytes.
    ///
    /// Errors: as [`emit_into`](Self::emit_into) (never a short buffer).
    fn to_vec(&self) -> Result<Vec<u8>> {
        let mut out = vec![0u8; self.wire_len()];
        self.emit_into(&mut out)?;
        Ok(out)
    }
}

/// `Emit` for a representation whose `emit` writes through a view type.
macro_rules! emit_through_view {
    ($($repr:ty => $view:ident),* $(,)?) => {$(
        impl Emit for $repr {
            fn wire_len(&self) -> usize {
                self.buffer_len()
            }

            fn emit_into(&self, buffer: &mut [u8]) -> Result<usize> {
                let len = self.buffer_len();
                room(stringify!($repr), buffer, len)?;
                let target = buffer.get_mut(..len).unwrap_or_default();
                self.emit(&mut $view::new_unchecked(target))?;
                Ok(len)
            }
        }
    )*};
}

/// `Emit` for a representation whose `emit` writes into a plain byte slice.
macro_rules! emit_into_slice {
    ($($repr:ty),* $(,)?) => {$(
        impl Emit for $repr {
            fn wire_len(&self) -> usize {
                self.buffer_len()
            }

            fn emit_into(&self, buffer: &mut [u8]) -> Result<usize> {
                let len = self.buffer_len();
                room(stringify!($repr), buffer, len)?;
                self.emit(buffer.get_mut(..len).unwrap_or_default())?;
                Ok(len)
            }
        }
    )*};
}

emit_through_view! {
    EthernetRepr => EthernetFrame,
    FrameHeader => Frame,
    DatagramRepr<'_> => Datagram,
    MailboxHeader => Mailbox,
    ErrorReplyRepr => ErrorReply,
    CoeHeaderRepr => CoeFrame,
    CoeRepr<'_> => CoeFrame,
    SdoRequest<'_> => SdoFrame,
    SdoResponse<'_> => SdoFrame,
    SdoInfoRepr<'_> => SdoInfoFrame,
    EmergencyRepr => EmergencyFrame,
    SoeRepr<'_> => SoePacket,
    FoeRepr<'_> => FoePacket,
    EoeRepr<'_> => EoePacket,
    FragmentRepr<'_> => EoePacket,
    VoeRepr<'_> => VoePacket,
    GatewayRepr<'_> => GatewayMessage,
    EscInfoRepr => EscInfo,
    AlStatusBlockRepr => AlStatusBlock,
    ErrorCountersRepr => ErrorCounters,
    EepromRequestRepr => EepromRequest,
    FmmuRepr => Fmmu,
    SyncManagerRepr => SyncManager,
    SiiFixedRepr => SiiFixed,
    CategoryRepr<'_> => Category,
}

emit_into_slice! {
    DcCategoryRepr,
    FmmuCategoryRepr,
    GeneralRepr,
    PdoCategoryRepr,
    StringsRepr<'_>,
    SyncmCategoryRepr,
}

impl Emit for MailboxMessage<'_> {
    fn wire_len(&self) -> usize {
        self.buffer_len()
    }

    fn emit_into(&self, buffer: &mut [u8]) -> Result<usize> {
        let len = self.buffer_len();
        room("MailboxMessage", buffer, len)?;
        self.emit(buffer.get_mut(..len).unwrap_or_default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::WireError;
    use crate::command::{Command, DatagramAddress};

    fn fprd() -> DatagramRepr<'static> {
        DatagramRepr::request(
            Command::Fprd,
            7,
            DatagramAddress::Node {
                station: 0x03E9,
                ado: 0x0130,
            },
            &[0x11, 0x22],
        )
    }

    #[test]
    fn to_vec_gives_the_bytes_of_the_view_emit() {
        let repr = fprd();
        let mut expected = vec![0u8; repr.buffer_len()];
        repr.emit(&mut Datagram::new_unchecked(&mut expected[..]))
            .unwrap();
        assert_eq!(repr.to_vec().unwrap(), expected);
        // FPRD, index 7, ADP 0x03E9, ADO 0x0130, length 2, IRQ 0, data, WKC 0.
        assert_eq!(
            expected,
            [
                0x04, 7, 0xE9, 0x03, 0x30, 0x01, 2, 0, 0, 0, 0x11, 0x22, 0, 0
            ]
        );
    }

    #[test]
    fn to_vec_of_a_slice_representation_pads_as_its_emit_does() {
        let repr = StringsRepr {
            strings: vec![b"abc"],
        };
        // Count 1, length 3, "abc", one padding byte to an even length.
        assert_eq!(repr.to_vec().unwrap(), [1, 3, b'a', b'b', b'c', 0]);
    }

    #[test]
    fn emit_into_writes_only_its_length_and_refuses_a_short_buffer() {
        let repr = SyncManagerRepr::mailbox_out(0x1000, 128);
        let mut long = [0xA5u8; 12];
        assert_eq!(repr.emit_into(&mut long).unwrap(), 8);
        assert_eq!(&long[..8], &repr.to_vec().unwrap()[..]);
        assert_eq!(long[8..], [0xA5; 4]);
        let mut short = [0xA5u8; 7];
        assert_eq!(
            repr.emit_into(&mut short),
            Err(WireError::BufferTooSmall {
                what: "SyncManagerRepr",
                need: 8,
                have: 7,
            })
        );
        assert_eq!(short, [0xA5; 7]);
    }

    #[test]
    fn to_vec_passes_on_the_representation_s_own_refusal() {
        let long = [0u8; 256];
        let repr = StringsRepr {
            strings: vec![&long[..]],
        };
        assert!(matches!(repr.to_vec(), Err(WireError::Invalid { .. })));
    }
}
