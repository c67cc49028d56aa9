//! The per-slave objects (ETG.1510, spec-notes §master-od): 0x8nnn configuration, 0x9nnn detected
//! information, 0xAnnn diagnosis, with n the slave's ring position.

use crate::master::{Identity, SlaveInfo};
use crate::od::{DictionaryBuilder, ObjectBuilder};
use crate::wire::coe::{DataType, ObjectAccess};
use crate::wire::register::{AlState, DlStatus, ErrorCountersRepr, PortType};

use super::snapshot::{MasterSnapshot, SlaveDiagnosis};
use super::text::fit;

/// Most slaves the dictionary describes (n = 0..=0xFFF).
pub const MAX_SLAVES: usize = 0x1000;
/// Capacity of 0x8nnn:02 (type) and :03 (name).
pub const SLAVE_TEXT_LEN: usize = 64;

/// First index of the configuration objects.
pub const CONFIGURATION: u16 = 0x8000;
/// First index of the information objects.
pub const INFORMATION: u16 = 0x9000;
/// First index of the diagnosis objects.
pub const DIAGNOSIS: u16 = 0xA000;
/// 0xAnnn:02, the writable AL control.
pub const AL_CONTROL_SUBINDEX: u8 = 2;

/// 0x8nnn:23 link status (PyETG1510's reading of ETG.1510, spec-notes §master-od): bit 0 no link at
/// all, bit 1 a port with a link but no communication; bits 4-7 say which ports bit 1 is
/// about.
fn link_status(dl: &DlStatus) -> u8 {
    let mut status = 0u8;
    if !dl.ports.iter().any(|p| p.link) {
        status |= 0x01;
    }
    for (n, port) in dl.ports.iter().enumerate() {
        if port.link && !port.communication {
            status |= 0x02 | (0x10 << n);
        }
    }
    status
}

/// 0x8nnn:24 link preset, as detected (no configuration file says otherwise): bits 0-2 port
/// 1..3 connected to a slave, bits 4-6 port 1..3 with a physical link.
fn link_preset(dl: &DlStatus) -> u8 {
    let mut preset = 0u8;
    for (bit, port) in dl.ports.iter().skip(1).enumerate() {
        if port.communication {
            preset |= 1 << bit;
        }
        if port.link {
            preset |= 0x10 << bit;
        }
    }
    preset
}

/// 0x8nnn:26 port physics, one nibble per port: 0 none, 1 MII, 3 EBUS (KickCAT's packing).
fn port_physics(ports: &[PortType; 4]) -> u16 {
    ports.iter().enumerate().fold(0u16, |acc, (n, port)| {
        let nibble = match port {
            PortType::Mii => 1,
            PortType::Ebus => 3,
            _ => 0,
        };
        acc | (nibble << (4 * n))
    })
}

/// 0xAnnn:04 link connection status: bits 0-3 port used for communication, bits 4-7 port
/// with a physical link.
fn link_connection(dl: &DlStatus) -> u8 {
    dl.ports.iter().enumerate().fold(0u8, |acc, (n, port)| {
        acc | (u8::from(port.communication) << n) | (u8::from(port.link) << (4 + n))
    })
}

/// AL status as the register holds it: state in bits 0-3, error in bit 4.
pub(crate) fn al_status_word(info: &SlaveInfo) -> u16 {
    u16::from(u8::from(info.al_state)) | if info.al_error { 0x10 } else { 0 }
}

/// The station address of the slave on each port of the slave at `position`, for a line
/// (port 0 towards the master, port 1 onwards); 0 where there is none.
fn neighbours(slaves: &[SlaveInfo], position: usize) -> [u16; 4] {
    let mut n = [0u16; 4];
    if let Some(prev) = position.checked_sub(1).and_then(|p| slaves.get(p)) {
        n[0] = prev.station;
    }
    let this = &slaves[position];
    if this.dl_status.ports[1].communication
        && let Some(next) = slaves.get(position + 1)
    {
        n[1] = next.station;
    }
    n
}

/// Frame errors of a port: invalid frames and RX errors together.
fn frame_errors(counters: &ErrorCountersRepr, port: usize) -> u32 {
    u32::from(counters.invalid_frame[port]) + u32::from(counters.rx_error[port])
}

/// Subindexes 5-8 of the configuration and information records: the identity.
fn identity_entries(r: ObjectBuilder, identity: &Identity) -> ObjectBuilder {
    let ro = ObjectAccess::RO;
    r.entry(5, "Vendor ID", DataType::Unsigned32, ro, identity.vendor_id)
        .entry(
            6,
            "Product code",
            DataType::Unsigned32,
            ro,
            identity.product_code,
        )
        .entry(
            7,
            "Revision number",
            DataType::Unsigned32,
            ro,
            identity.revision,
        )
        .entry(
            8,
            "Serial number",
            DataType::Unsigned32,
            ro,
            identity.serial,
        )
}

/// Declares the three objects of every slave.
pub(crate) fn declare(mut b: DictionaryBuilder, snap: &MasterSnapshot) -> DictionaryBuilder {
    let ro = ObjectAccess::RO;
    for (position, info) in snap.slaves.iter().enumerate().take(MAX_SLAVES) {
        let n = position as u16;
        let order = snap.order_codes.get(&n).map_or("", String::as_str);
        let mailbox = info.mailbox;
        let protocols = mailbox.map_or(0, |m| m.protocols.0);
        b = b.record(CONFIGURATION + n, "Configuration data", |r| {
            let r = r
                .entry(
                    1,
                    "Fixed station address",
                    DataType::Unsigned16,
                    ro,
                    info.station,
                )
                .string(2, "Type", ro, fit(order, SLAVE_TEXT_LEN), SLAVE_TEXT_LEN)
                .string(
                    3,
                    "Name",
                    ro,
                    fit(&info.name, SLAVE_TEXT_LEN),
                    SLAVE_TEXT_LEN,
                )
                .entry(4, "Device type", DataType::Unsigned32, ro, info.device_type);
            identity_entries(r, &info.identity)
                .entry(
                    0x21,
                    "Mailbox out size",
                    DataType::Unsigned16,
                    ro,
                    mailbox.map_or(0, |m| m.write.len),
                )
                .entry(
                    0x22,
                    "Mailbox in size",
                    DataType::Unsigned16,
                    ro,
                    mailbox.map_or(0, |m| m.read.len),
                )
                .entry(
                    0x23,
                    "Link status",
                    DataType::Unsigned8,
                    ro,
                    link_status(&info.dl_status),
                )
                .entry(
                    0x24,
                    "Link preset",
                    DataType::Unsigned8,
                    ro,
                    link_preset(&info.dl_status),
                )
                .entry(0x25, "Flags", DataType::Unsigned8, ro, 0u8)
                .entry(
                    0x26,
                    "Port physics",
                    DataType::Unsigned16,
                    ro,
                    port_physics(&info.esc.ports),
                )
                .entry(
                    0x27,
                    "Mailbox protocols supported",
                    DataType::Unsigned16,
                    ro,
                    protocols,
                )
        });
        b = b.record(INFORMATION + n, "Information data", |r| {
            let r = r.entry(
                1,
                "Fixed station address",
                DataType::Unsigned16,
                ro,
                info.station,
            );
            identity_entries(r, &info.identity).entry(
                0x20,
                "DL status",
                DataType::Unsigned16,
                ro,
                info.dl_status.encode(),
            )
        });
        let counters = snap.error_counters.get(&n).copied().unwrap_or_default();
        let diag: SlaveDiagnosis = snap.diagnosis.get(&n).copied().unwrap_or_default();
        let neighbours = neighbours(&snap.slaves, position);
        let requested = u16::from(u8::from(match info.requested_state {
            AlState::Unknown(_) => AlState::Init,
            s => s,
        }));
        b = b.record(DIAGNOSIS + n, "Diagnosis data", |r| {
            let mut r = r
                .entry(
                    1,
                    "AL status",
                    DataType::Unsigned16,
                    ro,
                    al_status_word(info),
                )
                .entry(
                    AL_CONTROL_SUBINDEX,
                    "AL control",
                    DataType::Unsigned16,
                    ObjectAccess::RW,
                    requested,
                )
                .entry(
                    3,
                    "Last AL status code",
                    DataType::Unsigned16,
                    ro,
                    u16::from(info.al_status_code),
                )
                .entry(
                    4,
                    "Link connection status",
                    DataType::Unsigned8,
                    ro,
                    link_connection(&info.dl_status),
                )
                .entry(5, "Link control", DataType::Unsigned8, ro, 0u8);
            for port in 0..4u8 {
                r = r.entry(
                    6 + port,
                    &format!("Fixed address connected port {port}"),
                    DataType::Unsigned16,
                    ro,
                    neighbours[usize::from(port)],
                );
            }
            for port in 0..4u8 {
                r = r.entry(
                    0x0A + port,
                    &format!("Frame error counter port {port}"),
                    DataType::Unsigned32,
                    ro,
                    frame_errors(&counters, usize::from(port)),
                );
            }
            r.entry(
                0x0E,
                "Cyclic working counter error counter",
                DataType::Unsigned32,
                ro,
                snap.wkc_errors.get(position).copied().unwrap_or(0),
            )
            .entry(
                0x0F,
                "Slave not present counter",
                DataType::Unsigned32,
                ro,
                diag.not_present,
            )
            .entry(
                0x10,
                "Abnormal state change counter",
                DataType::Unsigned32,
                ro,
                diag.abnormal_state_changes,
            )
        });
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::register::PortStatus;

    #[test]
    fn link_bits_follow_the_dl_status() {
        let mut dl = DlStatus::default();
        assert_eq!(link_status(&dl), 0x01);
        dl.ports[0] = PortStatus {
            link: true,
            loop_closed: false,
            communication: true,
        };
        dl.ports[1] = PortStatus {
            link: true,
            loop_closed: false,
            communication: false,
        };
        assert_eq!(link_status(&dl), 0x02 | 0x20);
        assert_eq!(link_preset(&dl), 0x10);
        assert_eq!(link_connection(&dl), 0x01 | 0x10 | 0x20);
        assert_eq!(
            port_physics(&[
                PortType::Mii,
                PortType::Ebus,
                PortType::NotImplemented,
                PortType::NotConfigured
            ]),
            0x0031
        );
    }
}
