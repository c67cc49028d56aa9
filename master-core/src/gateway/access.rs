//! Which requests write (docs/gateway.md, "Roles"): what a client with the `read` role may
//! not send, and what leaves an audit line. Decided on the standard form of the request
//! (after the compatibility translation and the SDO normalisation), so both layouts are
//! judged alike.
//!
//! | protocol | reads (allowed to `read`) | writes |
//! |---|---|---|
//! | CoE | SDO upload (initiate, segment), the client's SDO abort, SDO Information, TxPDO and RxPDO remote requests | SDO download (initiate, segment), RxPDO, anything else |
//! | SoE | read request | write request, anything else |
//! | FoE | read request, ACK, the client's ERROR | write request, DATA, BUSY |
//! | VoE, EoE | — | everything (their effect is unknown to the gateway) |
//!
//! The master's dictionary (address 0) is CoE: its downloads (AL state requests, rescan,
//! counter reset) are writes like any other.

use crate::wire::coe::{CoeFrame, CoeService, SdoFrame};
use crate::wire::foe::{FoeOpcode, FoePacket};
use crate::wire::mailbox::MailboxType;
use crate::wire::soe::{Idn, SoeOpcode, SoePacket};

/// The SDO command specifiers of a client's request that read (ETG.1000.6 §5.6.2, Table 38:
/// 2 initiate upload, 3 upload segment, 4 abort).
const SDO_READS: [u8; 3] = [2, 3, 4];

/// Whether a request of `ty` with standard data `data` writes.
pub(crate) fn is_write(ty: MailboxType, data: &[u8]) -> bool {
    match ty {
        MailboxType::Coe => match CoeFrame::new_checked(data).map(|f| f.service()) {
            Ok(CoeService::SdoRequest) => {
                SdoFrame::new_checked(data).map_or(true, |f| !SDO_READS.contains(&f.specifier()))
            }
            Ok(CoeService::SdoInfo | CoeService::TxPdoRemote | CoeService::RxPdoRemote) => false,
            _ => true,
        },
        MailboxType::Soe => {
            SoePacket::new_checked(data).map_or(true, |p| p.opcode() != SoeOpcode::ReadRequest)
        }
        MailboxType::Foe => FoePacket::new_checked(data).map_or(true, |p| {
            !matches!(
                p.opcode(),
                FoeOpcode::ReadRequest | FoeOpcode::Ack | FoeOpcode::Error
            )
        }),
        _ => true,
    }
}

/// Whether a write starts what an audit line records: the first message of a transfer (an
/// SDO download's initiate, an FoE write request, an SoE write's last or only fragment),
/// every VoE and EoE message; not the segments and packets that follow.
pub(crate) fn is_audited(ty: MailboxType, data: &[u8]) -> bool {
    match ty {
        MailboxType::Coe => SdoFrame::new_checked(data).map_or(true, |f| f.specifier() != 0),
        MailboxType::Soe => SoePacket::new_checked(data).map_or(true, |p| !p.incomplete()),
        MailboxType::Foe => {
            FoePacket::new_checked(data).map_or(true, |p| p.opcode() != FoeOpcode::Data)
        }
        _ => true,
    }
}

/// What a request names, for the audit line: `0x6040:00`, `S-0-0032 drive 0`,
/// `file firmware.bin`, `VoE vendor 0x00001164`, `EoE`.
pub(crate) fn object(ty: MailboxType, data: &[u8]) -> String {
    match ty {
        MailboxType::Coe => match SdoFrame::new_checked(data) {
            Ok(f)
                if CoeFrame::new_checked(data)
                    .is_ok_and(|c| c.service() == CoeService::SdoRequest) =>
            {
                format!("0x{:04X}:{:02X}", f.index(), f.subindex())
            }
            _ => "CoE".into(),
        },
        MailboxType::Soe => match SoePacket::new_checked(data) {
            Ok(p) => format!(
                "{} drive {}",
                Idn::from_raw(p.idn_or_fragments()),
                p.drive()
            ),
            Err(_) => "SoE".into(),
        },
        MailboxType::Foe => match FoePacket::new_checked(data) {
            Ok(p) => {
                let name = data.get(6..).unwrap_or_default();
                match p.opcode() {
                    FoeOpcode::WriteRequest | FoeOpcode::ReadRequest => {
                        format!("file {}", String::from_utf8_lossy(name).escape_debug())
                    }
                    other => format!("FoE {}", other.name()),
                }
            }
            Err(_) => "FoE".into(),
        },
        MailboxType::Voe => match data.get(..4) {
            Some(id) => format!(
                "VoE vendor 0x{:08X}",
                u32::from_le_bytes([id[0], id[1], id[2], id[3]])
            ),
            None => "VoE".into(),
        },
        other => other.name().into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_writes_are_told_apart() {
        let upload = [0x00, 0x20, 0x40, 0x40, 0x60, 0x00, 0, 0, 0, 0];
        let download = [0x00, 0x20, 0x2B, 0x40, 0x60, 0x00, 6, 0, 0, 0];
        let abort = [0x00, 0x20, 0x80, 0x40, 0x60, 0x00, 0, 0, 0, 0];
        let info = [0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00];
        assert!(!is_write(MailboxType::Coe, &upload));
        assert!(is_write(MailboxType::Coe, &download));
        assert!(!is_write(MailboxType::Coe, &abort));
        assert!(!is_write(MailboxType::Coe, &info));
        assert!(!is_write(MailboxType::Soe, &[0x01, 0x40, 0x20, 0x00]));
        assert!(is_write(MailboxType::Soe, &[0x03, 0x40, 0x20, 0x00, 1, 0]));
        assert!(!is_write(MailboxType::Foe, &[0x01, 0, 0, 0, 0, 0, b'f']));
        assert!(!is_write(MailboxType::Foe, &[0x04, 0, 1, 0, 0, 0]));
        assert!(is_write(MailboxType::Foe, &[0x02, 0, 0, 0, 0, 0, b'f']));
        assert!(is_write(MailboxType::Foe, &[0x03, 0, 1, 0, 0, 0, 9]));
        assert!(is_write(MailboxType::Voe, &[0x64, 0x11, 0, 0, 1, 0]));
        assert!(is_write(MailboxType::Eoe, &[]));
        assert_eq!(object(MailboxType::Coe, &download), "0x6040:00");
        assert_eq!(
            object(MailboxType::Foe, &[0x02, 0, 0, 0, 0, 0, b'f', b'w']),
            "file fw"
        );
        assert_eq!(
            object(MailboxType::Voe, &[0x64, 0x11, 0, 0, 1, 0]),
            "VoE vendor 0x00001164"
        );
    }
}
