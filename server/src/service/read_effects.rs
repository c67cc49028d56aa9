//! Register reads that change the slave: such a read needs the write role, even though
//! reading registers otherwise needs only the read role.
//!
//! - The mailbox SyncManager buffers (SM0 and SM1 as configured, standard and bootstrap
//!   mailbox): a mailbox SM hands its buffer over when its last byte is read, so a read over
//!   SM1's area empties the slave's send mailbox and takes the reply, emergency or EoE frame
//!   another caller waits for (ETG.1000.4 §6.7, Table 59; `spec-notes §esc.sm`). SM0's area
//!   is the master's outgoing buffer; it is guarded alike, being the same handshake.
//! - SYNC0/SYNC1 status 0x098E-0x098F: reading clears the "triggered" bit in acknowledge
//!   mode (ETG.1000.4 §6.8, Table 60; `spec-notes §esc.dc`).

use master_core::mailbox::SlaveMailboxConfig;
use master_core::master::SlaveInfo;

/// Fixed registers whose read has a side effect: first address, length, what they are.
const FIXED: &[(u16, u16, &str)] = &[(0x098E, 2, "SYNC0/SYNC1 status")];

/// What the read of `len` bytes from `address` on `slave` would disturb, if anything.
pub fn side_effect(slave: &SlaveInfo, address: u16, len: usize) -> Option<String> {
    in_areas(
        [
            ("", slave.mailbox.as_ref()),
            ("bootstrap ", slave.boot_mailbox.as_ref()),
        ],
        address,
        len,
    )
}

/// [`side_effect`] over the slave's standard and bootstrap mailbox layouts.
fn in_areas(
    mailboxes: [(&str, Option<&SlaveMailboxConfig>); 2],
    address: u16,
    len: usize,
) -> Option<String> {
    let start = u32::from(address);
    let end = u32::try_from(len).unwrap_or(u32::MAX).saturating_add(start);
    let overlaps = |area_start: u16, area_len: u16| {
        let a = u32::from(area_start);
        area_len > 0 && start < a + u32::from(area_len) && a < end
    };
    for (kind, config) in mailboxes {
        let Some(config) = config else { continue };
        for (sm, area) in [("SM0", config.write), ("SM1", config.read)] {
            if overlaps(area.start, area.len) {
                return Some(format!(
                    "the {kind}mailbox buffer of {sm} (0x{:04X}, {} bytes)",
                    area.start, area.len
                ));
            }
        }
    }
    FIXED
        .iter()
        .find(|(a, l, _)| overlaps(*a, *l))
        .map(|(a, _, name)| format!("{name} (0x{a:04X}, cleared by reading)"))
}

#[cfg(test)]
mod tests {
    use master_core::mailbox::{MailboxArea, MailboxProtocols};

    use super::*;

    fn config(write: u16, read: u16, len: u16) -> SlaveMailboxConfig {
        SlaveMailboxConfig {
            station: 0x1001,
            write: MailboxArea { start: write, len },
            read: MailboxArea { start: read, len },
            protocols: MailboxProtocols::default(),
        }
    }

    #[test]
    fn mailbox_areas_and_clearing_registers_are_found() {
        let standard = config(0x1000, 0x1080, 0x80);
        let boot = config(0x1800, 0x1C00, 0x100);
        let areas = [("", Some(&standard)), ("bootstrap ", Some(&boot))];
        let effect = |address, len| in_areas(areas, address, len);
        // SM1: its first and last byte, and a read that ends in it.
        assert!(effect(0x1080, 1).unwrap().contains("SM1"));
        assert!(effect(0x10FF, 1).unwrap().contains("SM1"));
        assert!(effect(0x107E, 4).is_some());
        assert!(effect(0x1000, 1).unwrap().contains("SM0"));
        assert!(effect(0x1C10, 2).unwrap().contains("bootstrap"));
        assert!(effect(0x098F, 1).unwrap().contains("SYNC"));
        assert!(
            effect(0x0900, 0x1000).is_some(),
            "a read spanning everything"
        );
        // Next to the areas, and plain registers: no side effect.
        assert_eq!(effect(0x1100, 0x10), None);
        assert_eq!(effect(0x0FFE, 2), None);
        assert_eq!(effect(0x0130, 2), None);
        assert_eq!(effect(0x0808, 8), None, "SM1's own registers");
        assert_eq!(effect(0x098D, 1), None);
        assert_eq!(in_areas([("", None), ("", None)], 0x1080, 1), None);
        assert_eq!(effect(0xFFFF, 0x1000), None, "no overflow past 0xFFFF");
    }
}
