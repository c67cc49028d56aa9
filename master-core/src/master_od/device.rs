//! The device-level objects (spec-notes §master-od): 0xF000 modular device profile, 0xF002 scan
//! command, 0xF020.. configured and 0xF040.. detected address lists, 0xF120 master
//! diagnosis, 0xF200 diagnosis reset.

use crate::od::{DictionaryBuilder, Entry};
use crate::wire::coe::{DataType, ObjectAccess};
use crate::wire::register::AlState;

use super::slaves::MAX_SLAVES;
use super::snapshot::MasterSnapshot;

/// The scan command object.
pub const SCAN_COMMAND: u16 = 0xF002;
/// 0xF002:01 value that starts a scan (u16 1, little endian).
pub const SCAN_REQUEST: [u8; 2] = [0x01, 0x00];
/// First configured address list.
pub const CONFIGURED_ADDRESSES: u16 = 0xF020;
/// First detected address list.
pub const DETECTED_ADDRESSES: u16 = 0xF040;
/// Addresses per list object.
pub const ADDRESSES_PER_OBJECT: usize = 255;
/// The master diagnosis object.
pub const MASTER_DIAGNOSIS: u16 = 0xF120;
/// The diagnosis interface control object.
pub const DIAGNOSIS_CONTROL: u16 = 0xF200;
/// 0xF200:10, "reset diagnosis information".
pub const RESET_DIAGNOSIS_SUBINDEX: u8 = 0x10;

/// 0xF120:10 master state: the lowest AL state of the slaves that answered (the state the
/// segment as a whole has reached), 0 if there are none.
fn master_state(snap: &MasterSnapshot) -> u16 {
    let rank = |s: AlState| match s {
        AlState::Init | AlState::Boot => 0,
        AlState::PreOp => 1,
        AlState::SafeOp => 2,
        AlState::Op => 3,
        AlState::Unknown(_) => 0,
    };
    snap.slaves
        .iter()
        .filter(|s| s.present)
        .map(|s| s.al_state)
        .min_by_key(|s| rank(*s))
        .map_or(0, |s| u16::from(u8::from(s)))
}

fn address_lists(
    mut b: DictionaryBuilder,
    first: u16,
    name: &str,
    addresses: &[u16],
) -> DictionaryBuilder {
    // At least one object, so a client always finds the list (with 0 entries).
    let chunks: Vec<&[u16]> = if addresses.is_empty() {
        vec![&[]]
    } else {
        addresses.chunks(ADDRESSES_PER_OBJECT).collect()
    };
    for (i, chunk) in chunks.into_iter().enumerate() {
        let index = first + i as u16;
        b = b.array_with(index, name, DataType::Unsigned16, |mut a| {
            for (j, &address) in chunk.iter().enumerate() {
                let sub = j as u8 + 1;
                a = a.entry(
                    sub,
                    &format!("Address {sub:03}"),
                    DataType::Unsigned16,
                    ObjectAccess::RO,
                    address,
                );
            }
            a
        });
    }
    b
}

/// Declares the device-level objects.
pub(crate) fn declare(b: DictionaryBuilder, snap: &MasterSnapshot) -> DictionaryBuilder {
    let ro = ObjectAccess::RO;
    let b = b
        .record(0xF000, "Modular device profile", |r| {
            r.entry(1, "Module index distance", DataType::Unsigned16, ro, 1u16)
                .entry(
                    2,
                    "Maximum number of modules",
                    DataType::Unsigned16,
                    ro,
                    MAX_SLAVES as u16,
                )
                .entry(
                    3,
                    "General configuration",
                    DataType::Unsigned32,
                    ro,
                    0xFFu32,
                )
                .entry(4, "General information", DataType::Unsigned32, ro, 0u32)
        })
        .record(SCAN_COMMAND, "Detect modules command", |r| {
            let status = snap.scan;
            let mut response = [0u8; 6];
            response[..2].copy_from_slice(&status.found.to_le_bytes());
            response[2..4].copy_from_slice(&status.failures.to_le_bytes());
            r.raw(Entry::with_capacity(
                1,
                "Scan command request",
                DataType::OctetString,
                ObjectAccess::RW,
                vec![0, 0],
                2,
            ))
            .entry(
                2,
                "Scan command status",
                DataType::Unsigned8,
                ro,
                status.status,
            )
            .raw(Entry::with_capacity(
                3,
                "Scan command response",
                DataType::OctetString,
                ro,
                response.to_vec(),
                6,
            ))
        });
    let configured: Vec<u16> = snap
        .slaves
        .iter()
        .take(MAX_SLAVES)
        .map(|s| s.station)
        .collect();
    let detected: Vec<u16> = snap
        .slaves
        .iter()
        .take(MAX_SLAVES)
        .filter(|s| s.present)
        .map(|s| s.station)
        .collect();
    let b = address_lists(
        b,
        CONFIGURED_ADDRESSES,
        "Configured address list",
        &configured,
    );
    let b = address_lists(b, DETECTED_ADDRESSES, "Detected address list", &detected);
    let sat = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
    b.record(MASTER_DIAGNOSIS, "Master diagnosis data", |r| {
        r.entry(
            1,
            "Cyclic lost frames",
            DataType::Unsigned32,
            ro,
            sat(snap.cyclic_lost),
        )
        .entry(
            2,
            "Acyclic lost frames",
            DataType::Unsigned32,
            ro,
            sat(snap.acyclic_lost),
        )
        .entry(
            3,
            "Cyclic frames per second",
            DataType::Unsigned32,
            ro,
            snap.rates.cyclic,
        )
        .entry(
            4,
            "Acyclic frames per second",
            DataType::Unsigned32,
            ro,
            snap.rates.acyclic,
        )
        .entry(
            0x10,
            "Master state",
            DataType::Unsigned16,
            ro,
            master_state(snap),
        )
    })
    .record(DIAGNOSIS_CONTROL, "Diagnosis interface control", |r| {
        r.entry(
            RESET_DIAGNOSIS_SUBINDEX,
            "Reset diagnosis information",
            DataType::Boolean,
            ObjectAccess::RW,
            false,
        )
    })
}
