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

use master_core::master::SlaveInfo;

/// Fixed registers whose read has a side effect: first address, length, what they are.
const FIXED: &[(u16, u16, &str)] = &[(0x098E, 2, "SYNC0/SYNC1 status")];

/// What the read of `len` bytes from `address` on `slave` would disturb, if anything.
pub fn side_effect(slave: &SlaveInfo, address: u16, len: usize) -> Option<String> {
    let start = u32::from(address);
    let end = u32::try_from(len).unwrap_or(u32::MAX).saturating_add(start);
    let overlaps = |area_start: u16, area_len: u16| {
        let a = u32::from(area_start);
        area_len > 0 && start < a + u32::from(area_len) && a < end
    };
    let mailboxes = [("", &slave.mailbox), ("bootstrap ", &slave.boot_mailbox)];
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
