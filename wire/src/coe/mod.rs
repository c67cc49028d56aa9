//! CANopen over EtherCAT (mailbox type 3, ETG.1000.6, spec-notes §coe.sdo).
//!
//! Every view here wraps the *mailbox data* (the bytes after the 6-byte mailbox header,
//! exactly `length` of them, starting with the CoE header), so the view's length is the
//! mailbox length. [`CoeRepr`] dispatches on the CoE service; the meaning of an SDO command
//! byte depends on it (service 2 request vs 3 response).
//!
//! - [`header`]: the CoE header and [`CoeService`];
//! - [`sdo`], [`sdo_payload`], [`sdo_request`], [`sdo_response`]: SDO transfers;
//! - [`abort`]: abort codes; [`emergency`]: emergencies; [`info`]: SDO Information;
//! - [`data_type`]: data types, object codes and access flags for object dictionaries.

pub mod abort;
pub mod data_type;
mod display;
pub mod emergency;
pub mod header;
pub mod info;
pub mod sdo;
pub mod sdo_payload;
pub mod sdo_request;
pub mod sdo_response;

use core::fmt;

pub use abort::{AbortCode, sdo_abort};
pub use data_type::{DataType, ObjectAccess, ObjectCode};
pub use emergency::{EmergencyFrame, EmergencyRepr};
pub use header::{COE_HEADER_LEN, CoeFrame, CoeHeaderRepr, CoeService};
pub use info::{SdoInfoFrame, SdoInfoRepr, SdoInfoService};
pub use sdo::{SdoFrame, max_initiate_data, max_segment_data};
pub use sdo_payload::SdoPayload;
pub use sdo_request::SdoRequest;
pub use sdo_response::SdoResponse;

use crate::error::{Result, WireError, room};
use display::Hex;

/// Any CoE message, by service.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CoeRepr<'a> {
    /// Service 1.
    Emergency(EmergencyRepr),
    /// Service 2.
    SdoRequest(SdoRequest<'a>),
    /// Service 3.
    SdoResponse(SdoResponse<'a>),
    /// Service 8.
    SdoInfo(SdoInfoRepr<'a>),
    /// PDO services (4-7) and unknown services: header and raw bytes after it.
    Other {
        /// The CoE header (number and service).
        header: CoeHeaderRepr,
        /// The bytes after the CoE header.
        data: &'a [u8],
    },
}

impl<'a> CoeRepr<'a> {
    /// Parses CoE mailbox data. The PDO number of SDO, SDO Info and emergency messages is
    /// ignored (it is 0 on the wire).
    pub fn parse(frame: &CoeFrame<&'a [u8]>) -> Result<Self> {
        let header = CoeHeaderRepr::parse(frame)?;
        let bytes = frame.bytes();
        Ok(match header.service {
            CoeService::Emergency => {
                CoeRepr::Emergency(EmergencyRepr::parse(&EmergencyFrame::new_checked(bytes)?)?)
            }
            CoeService::SdoRequest => {
                CoeRepr::SdoRequest(SdoRequest::parse(&SdoFrame::new_checked(bytes)?)?)
            }
            CoeService::SdoResponse => {
                CoeRepr::SdoResponse(SdoResponse::parse(&SdoFrame::new_checked(bytes)?)?)
            }
            CoeService::SdoInfo => {
                CoeRepr::SdoInfo(SdoInfoRepr::parse(&SdoInfoFrame::new_checked(bytes)?)?)
            }
            _ => CoeRepr::Other {
                header,
                data: bytes.get(COE_HEADER_LEN..).unwrap_or(&[]),
            },
        })
    }

    /// Mailbox length of the message (CoE header included).
    pub fn buffer_len(&self) -> usize {
        match self {
            CoeRepr::Emergency(e) => e.buffer_len(),
            CoeRepr::SdoRequest(r) => r.buffer_len(),
            CoeRepr::SdoResponse(r) => r.buffer_len(),
            CoeRepr::SdoInfo(r) => r.buffer_len(),
            CoeRepr::Other { data, .. } => COE_HEADER_LEN + data.len(),
        }
    }

    /// Writes the message. `Other` is refused for the services that have their own variant
    /// (it would not parse back as `Other`) and for header values wider than their bits.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut CoeFrame<T>) -> Result<()> {
        let buf = frame.buffer_mut();
        match self {
            CoeRepr::Emergency(e) => e.emit(&mut EmergencyFrame::new_unchecked(buf)),
            CoeRepr::SdoRequest(r) => r.emit(&mut SdoFrame::new_unchecked(buf)),
            CoeRepr::SdoResponse(r) => r.emit(&mut SdoFrame::new_unchecked(buf)),
            CoeRepr::SdoInfo(r) => r.emit(&mut SdoInfoFrame::new_unchecked(buf)),
            CoeRepr::Other { header, data } => {
                if matches!(
                    header.service,
                    CoeService::Emergency
                        | CoeService::SdoRequest
                        | CoeService::SdoResponse
                        | CoeService::SdoInfo
                ) {
                    return Err(WireError::Invalid {
                        what: "CoE message",
                        reason: "raw form used for a service with its own representation",
                    });
                }
                header.validate()?;
                let len = COE_HEADER_LEN + data.len();
                room("CoE message", buf, len)?;
                let mut out = CoeFrame::new_unchecked(&mut buf[..len]);
                header.emit(&mut out)?;
                out.payload_mut().copy_from_slice(data);
                Ok(())
            }
        }
    }
}

impl fmt::Display for CoeRepr<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CoeRepr::Emergency(e) => e.fmt(f),
            CoeRepr::SdoRequest(r) => r.fmt(f),
            CoeRepr::SdoResponse(r) => r.fmt(f),
            CoeRepr::SdoInfo(r) => r.fmt(f),
            CoeRepr::Other { header, data } => {
                write!(f, "{header} {} bytes {}", data.len(), Hex(data))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::header::tests::arb_coe_header;
    use super::*;
    use crate::Emit;
    use crate::mailbox::{Mailbox, MailboxType};
    use proptest::prelude::*;

    fn parse(data: &[u8]) -> Result<CoeRepr<'_>> {
        CoeRepr::parse(&CoeFrame::new_checked(data)?)
    }

    #[test]
    fn dispatch_by_service() {
        // The worked upload of spec-notes §coe.sdo: the same command specifier bits mean different things.
        let req = [0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0];
        assert!(matches!(
            parse(&req).unwrap(),
            CoeRepr::SdoRequest(SdoRequest::InitiateUpload { index: 0x1018, .. })
        ));
        // 0x60 is an upload segment request in service 2 ...
        let seg = [0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(
            parse(&seg).unwrap(),
            CoeRepr::SdoRequest(SdoRequest::UploadSegment { toggle: false })
        );
        // ... and an initiate download response in service 3.
        let ack = [0x00, 0x30, 0x60, 0x12, 0x1c, 0x01, 0, 0, 0, 0];
        assert_eq!(
            parse(&ack).unwrap(),
            CoeRepr::SdoResponse(SdoResponse::InitiateDownload {
                index: 0x1C12,
                subindex: 1,
                complete_access: false
            })
        );
        let emcy = [0x00, 0x10, 0x00, 0xff, 0x01, 0, 0, 0, 0, 0];
        assert!(matches!(parse(&emcy).unwrap(), CoeRepr::Emergency(_)));
        let info = [0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00];
        assert!(matches!(parse(&info).unwrap(), CoeRepr::SdoInfo(_)));
        // RxPDO number 1 with 2 bytes of process data.
        let pdo = [0x01, 0x50, 0xaa, 0xbb];
        let r = parse(&pdo).unwrap();
        assert_eq!(
            r,
            CoeRepr::Other {
                header: CoeHeaderRepr {
                    number: 1,
                    service: CoeService::RxPdo
                },
                data: &[0xaa, 0xbb]
            }
        );
        assert_eq!(r.to_string(), "CoE RxPDO number 1 2 bytes [aa bb]");
    }

    #[test]
    fn c8_through_the_mailbox() {
        let bytes = [
            0x0a, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x30, 0x80, 0x00, 0x20, 0x00, 0x00, 0x00,
            0x02, 0x06,
        ];
        let mbx = Mailbox::new_checked(&bytes[..]).unwrap();
        assert_eq!(mbx.mailbox_type(), MailboxType::Coe);
        let r = parse(mbx.data()).unwrap();
        assert_eq!(
            r.to_string(),
            "CoE SDO abort 0x2000:00 0x06020000 Object does not exist in the object dictionary"
        );
        let mut out = vec![0xa5; r.buffer_len()];
        r.emit(&mut CoeFrame::new_unchecked(&mut out[..])).unwrap();
        assert_eq!(out, mbx.data());
    }

    #[test]
    fn errors() {
        assert!(parse(&[0x00]).is_err());
        assert!(parse(&[0x00, 0x20, 0x40]).is_err());
        assert!(parse(&[0x00, 0x10, 0x00]).is_err());
        let mut out = [0u8; 8];
        let bad = CoeRepr::Other {
            header: CoeHeaderRepr {
                number: 0,
                service: CoeService::SdoRequest,
            },
            data: &[],
        };
        assert!(
            bad.emit(&mut CoeFrame::new_unchecked(&mut out[..]))
                .is_err()
        );
        let too_long = CoeRepr::Other {
            header: CoeHeaderRepr {
                number: 0,
                service: CoeService::TxPdo,
            },
            data: &[1; 7],
        };
        assert!(matches!(
            too_long.emit(&mut CoeFrame::new_unchecked(&mut out[..])),
            Err(WireError::BufferTooSmall { .. })
        ));
        assert_eq!(out, [0u8; 8]);
    }

    proptest! {
        #[test]
        fn round_trip_other(
            header in arb_coe_header(),
            data in proptest::collection::vec(any::<u8>(), 0..20),
        ) {
            let repr = CoeRepr::Other { header, data: &data };
            match repr.to_vec() {
                Ok(out) => prop_assert_eq!(parse(&out).unwrap(), repr),
                Err(_) => prop_assert!(matches!(
                    header.service,
                    CoeService::Emergency
                        | CoeService::SdoRequest
                        | CoeService::SdoResponse
                        | CoeService::SdoInfo
                )),
            }
        }

        /// Whatever parses re-emits to bytes that parse to the same representation.
        #[test]
        fn reparse_is_stable(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            if let Ok(repr) = parse(&bytes) {
                let _ = repr.to_string();
                let out = repr.to_vec().unwrap();
                prop_assert_eq!(parse(&out).unwrap(), repr);
            }
        }

        /// The same, biased to the services with their own representation.
        #[test]
        fn reparse_is_stable_known_services(
            service in proptest::sample::select(vec![0x10u8, 0x20, 0x30, 0x80]),
            tail in proptest::collection::vec(any::<u8>(), 0..40),
        ) {
            let mut bytes = vec![0x00, service];
            bytes.extend_from_slice(&tail);
            if let Ok(repr) = parse(&bytes) {
                let _ = repr.to_string();
                let out = repr.to_vec().unwrap();
                prop_assert_eq!(parse(&out).unwrap(), repr);
            }
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = parse(&bytes);
        }
    }
}
