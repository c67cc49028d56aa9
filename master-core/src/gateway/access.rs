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

use crate::wire::foe::FoeOpcode;
use crate::wire::soe::SoeOpcode;

use super::ask::{Ask, What};

/// The SDO command specifiers of a client's request that read (ETG.1000.6 §5.6.2, Table 38:
/// 2 initiate upload, 3 upload segment, 4 abort).
const SDO_READS: [u8; 3] = [2, 3, 4];

impl Ask {
    /// Whether the request writes.
    pub(crate) fn is_write(&self) -> bool {
        match &self.what {
            What::Sdo { specifier, .. } => !SDO_READS.contains(specifier),
            What::SdoInfo | What::PdoRemote => false,
            What::Soe { opcode, .. } => *opcode != SoeOpcode::ReadRequest,
            What::Foe { opcode, .. } => !matches!(
                opcode,
                FoeOpcode::ReadRequest | FoeOpcode::Ack | FoeOpcode::Error
            ),
            What::Eoe { .. } | What::Voe { .. } | What::Opaque => true,
        }
    }

    /// Whether a write starts what an audit line records: the first message of a transfer
    /// (an SDO download's initiate, an FoE write request, an SoE write's last or only
    /// fragment), every VoE and EoE message; not the segments and packets that follow.
    pub(crate) fn is_audited(&self) -> bool {
        match &self.what {
            What::Sdo { specifier, .. } => *specifier != 0,
            What::Soe { incomplete, .. } => !incomplete,
            What::Foe { opcode, .. } => *opcode != FoeOpcode::Data,
            _ => true,
        }
    }

    /// What the request names, for the audit line: `0x6040:00`, `S-0-0032 drive 0`,
    /// `file firmware.bin`, `VoE vendor 0x00001164`, `EoE`.
    pub(crate) fn object(&self) -> String {
        match &self.what {
            What::Sdo {
                index, subindex, ..
            } => format!("0x{index:04X}:{subindex:02X}"),
            What::Soe { idn, drive, .. } => format!("{idn} drive {drive}"),
            What::Foe {
                file: Some(file), ..
            } => format!("file {file}"),
            What::Foe { opcode, .. } => format!("FoE {}", opcode.name()),
            What::Voe {
                vendor: Some(vendor),
            } => format!("VoE vendor 0x{vendor:08X}"),
            _ => self.ty.name().into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::mailbox::MailboxType;

    fn is_write(ty: MailboxType, data: &[u8]) -> bool {
        Ask::read(ty, data).is_write()
    }

    fn object(ty: MailboxType, data: &[u8]) -> String {
        Ask::read(ty, data).object()
    }

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
