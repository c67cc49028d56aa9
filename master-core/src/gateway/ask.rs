//! What a request asks, read once: the protocol body of a gateway request (in its standard
//! form, after the compatibility translation and the SDO normalisation) is decoded here and
//! nowhere else. Access and the audit line (`access`), the broadcast rule and the transfer
//! steps (`transfer`) and the gateway's own error answers (`answer`, `compat::errors`) read
//! the [`Ask`] this makes.
//!
//! Bytes a protocol header does not parse are still forwarded (the slave answers them as
//! it would any client): they classify as [`What::Opaque`], or for EoE as a message that
//! gets no answer, which is what the gateway assumed of them before it looked.

use crate::wire::coe::{CoeFrame, CoeService, SdoFrame, SdoPayload, SdoRequest};
use crate::wire::eoe::{EoeFrameType, EoePacket};
use crate::wire::foe::{FoeOpcode, FoePacket, FoeRepr};
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::{ElementFlags, Idn, SoeOpcode, SoePacket};

/// One request's protocol and what it asks of the slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Ask {
    /// The mailbox type of the request.
    pub ty: MailboxType,
    /// What the mailbox data ask.
    pub what: What,
}

/// What the mailbox data of a request ask, by protocol (ETG.1000.6 §5.6-§5.9).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum What {
    /// A CoE SDO request: the client command specifier of its header (ETG.1000.6 §5.6.2:
    /// 0 download segment, 1 initiate download, 2 initiate upload, 3 upload segment,
    /// 4 abort), the object its header names, and the transfer step the whole request
    /// parses to (`None` when only the header reads).
    Sdo {
        specifier: u8,
        index: u16,
        subindex: u8,
        step: Option<SdoStep>,
    },
    /// A CoE SDO Information request.
    SdoInfo,
    /// A CoE TxPDO or RxPDO remote request.
    PdoRemote,
    /// An SoE request: its opcode, whether more fragments follow, the IDN, the drive and the
    /// elements it names.
    Soe {
        opcode: SoeOpcode,
        incomplete: bool,
        idn: Idn,
        drive: u8,
        elements: ElementFlags,
    },
    /// An FoE packet: the opcode of its header, the file name a read or write request
    /// names, and the packet the whole message parses to (`None` when only the header
    /// reads).
    Foe {
        opcode: FoeOpcode,
        file: Option<String>,
        step: Option<FoeStep>,
    },
    /// An EoE message; `answered` is false for a frame fragment (and for bytes whose EoE
    /// header does not parse), which the slave does not answer.
    Eoe { answered: bool },
    /// A VoE message with the vendor id of its header, when it has one.
    Voe { vendor: Option<u32> },
    /// Another CoE service, a CoE, SoE or FoE message whose header does not parse, or
    /// another protocol: a write of unknown effect, answered once.
    Opaque,
}

/// The step of an SDO transfer a request takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SdoStep {
    /// An initiate upload.
    Upload,
    /// An upload segment request.
    UploadSegment,
    /// An initiate download; `segmented` when the data it carries are fewer than the size it
    /// announces (segments follow).
    Download { segmented: bool },
    /// A download segment; `last` when no segment follows.
    DownloadSegment { last: bool },
    /// Any other request (the client's abort, a block transfer).
    Other,
}

/// The FoE packet a request is (ETG.1000.6 §5.8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FoeStep {
    /// A read request.
    ReadRequest,
    /// A write request.
    WriteRequest,
    /// A DATA packet carrying `len` bytes of the file.
    Data { len: usize },
    /// An ACK.
    Ack,
    /// An ERROR.
    Error,
    /// A BUSY.
    Busy,
}

impl Ask {
    /// Reads the request of `ty` with standard mailbox data `data`.
    pub(crate) fn read(ty: MailboxType, data: &[u8]) -> Ask {
        let what = match ty {
            MailboxType::Coe => coe(data),
            MailboxType::Soe => soe(data),
            MailboxType::Foe => foe(data),
            MailboxType::Eoe => What::Eoe {
                answered: EoePacket::new_checked(data)
                    .is_ok_and(|p| p.frame_type() != EoeFrameType::Fragment),
            },
            MailboxType::Voe => What::Voe {
                vendor: data
                    .get(..4)
                    .map(|id| u32::from_le_bytes([id[0], id[1], id[2], id[3]])),
            },
            _ => What::Opaque,
        };
        Ask { ty, what }
    }
}

fn coe(data: &[u8]) -> What {
    match CoeFrame::new_checked(data).map(|f| f.service()) {
        Ok(CoeService::SdoRequest) => match SdoFrame::new_checked(data) {
            Ok(frame) => What::Sdo {
                specifier: frame.specifier(),
                index: frame.index(),
                subindex: frame.subindex(),
                step: SdoRequest::parse(&frame).ok().map(|r| sdo_step(&r)),
            },
            Err(_) => What::Opaque,
        },
        Ok(CoeService::SdoInfo) => What::SdoInfo,
        Ok(CoeService::TxPdoRemote | CoeService::RxPdoRemote) => What::PdoRemote,
        _ => What::Opaque,
    }
}

fn sdo_step(request: &SdoRequest<'_>) -> SdoStep {
    match request {
        SdoRequest::InitiateUpload { .. } => SdoStep::Upload,
        SdoRequest::UploadSegment { .. } => SdoStep::UploadSegment,
        SdoRequest::InitiateDownload { payload, .. } => SdoStep::Download {
            segmented: matches!(
                payload,
                SdoPayload::Normal { complete_size, data }
                    if (data.len() as u64) < u64::from(*complete_size)
            ),
        },
        SdoRequest::DownloadSegment { last, .. } => SdoStep::DownloadSegment { last: *last },
        _ => SdoStep::Other,
    }
}

fn soe(data: &[u8]) -> What {
    match SoePacket::new_checked(data) {
        Ok(p) => What::Soe {
            opcode: p.opcode(),
            incomplete: p.incomplete(),
            idn: Idn::from_raw(p.idn_or_fragments()),
            drive: p.drive(),
            elements: p.elements(),
        },
        Err(_) => What::Opaque,
    }
}

fn foe(data: &[u8]) -> What {
    let Ok(packet) = FoePacket::new_checked(data) else {
        return What::Opaque;
    };
    let opcode = packet.opcode();
    // The file name follows the opcode and the password (ETG.1000.6 §5.8).
    let file = matches!(opcode, FoeOpcode::ReadRequest | FoeOpcode::WriteRequest).then(|| {
        String::from_utf8_lossy(data.get(6..).unwrap_or_default())
            .escape_debug()
            .to_string()
    });
    let step = FoeRepr::parse(&packet).ok().map(|repr| match repr {
        FoeRepr::ReadRequest { .. } => FoeStep::ReadRequest,
        FoeRepr::WriteRequest { .. } => FoeStep::WriteRequest,
        FoeRepr::Data { data, .. } => FoeStep::Data { len: data.len() },
        FoeRepr::Ack { .. } => FoeStep::Ack,
        FoeRepr::Error { .. } => FoeStep::Error,
        FoeRepr::Busy { .. } => FoeStep::Busy,
    });
    What::Foe { opcode, file, step }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Emit;

    #[test]
    fn each_protocol_is_read_into_what_it_asks() {
        let download = [0x00, 0x20, 0x2B, 0x40, 0x60, 0x00, 6, 0, 0, 0];
        assert_eq!(
            Ask::read(MailboxType::Coe, &download).what,
            What::Sdo {
                specifier: 1,
                index: 0x6040,
                subindex: 0,
                step: Some(SdoStep::Download { segmented: false })
            }
        );
        let info = [0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00];
        assert_eq!(Ask::read(MailboxType::Coe, &info).what, What::SdoInfo);
        assert_eq!(Ask::read(MailboxType::Coe, &[0x00]).what, What::Opaque);
        assert_eq!(
            Ask::read(MailboxType::Soe, &[0x0B, 0x40, 0x02, 0x00, 1, 2]).what,
            What::Soe {
                opcode: SoeOpcode::WriteRequest,
                incomplete: true,
                idn: Idn::from_raw(2),
                drive: 0,
                elements: ElementFlags::VALUE,
            }
        );
        let wrq = FoeRepr::WriteRequest {
            password: 0,
            file_name: b"fw\n",
        }
        .to_vec()
        .unwrap();
        assert_eq!(
            Ask::read(MailboxType::Foe, &wrq).what,
            What::Foe {
                opcode: FoeOpcode::WriteRequest,
                file: Some("fw\\n".into()),
                step: Some(FoeStep::WriteRequest),
            }
        );
        assert_eq!(
            Ask::read(MailboxType::Voe, &[0x64, 0x11, 0, 0, 1, 0]).what,
            What::Voe {
                vendor: Some(0x1164)
            }
        );
        assert_eq!(
            Ask::read(MailboxType::Eoe, &[]).what,
            What::Eoe { answered: false }
        );
    }
}
