//! The drive's diagnosis history object 0x10F3 (ETG.1020 §13, spec-notes §coe.diag): a ring
//! of four message slots of which three are filled, so that a master's reader (`ecat diag`)
//! has an info, a warning and an error message to decode, with typed, byte-array and string
//! parameters.
//!
//! A message is DiagCode (u32), flags (u16: type in bits 0-3, 0 info / 1 warning / 2 error;
//! bit 4 local time stamp; number of parameters in bits 8-15), text ID (u16), time stamp
//! (u64, ns), then each parameter as its flags (u16: kind in bits 12-15, 0 a CoE data type
//! whose index is bits 0-11, 1 a byte array and 2 an ASCII string of bits 0-11 bytes) and
//! its bytes; all little-endian.

use super::model::CoeObject;

/// Subindex of the first message slot (ETG.1020 §13: subindices 1-5 are the header).
const FIRST_MESSAGE: u8 = 6;
/// Message slots.
const SLOTS: u8 = 4;

/// One parameter of a simulated message.
enum Param<'a> {
    /// CoE UNSIGNED16 (data type 0x0006).
    U16(u16),
    /// CoE UNSIGNED32 (data type 0x0007).
    U32(u32),
    /// A byte array.
    Bytes(&'a [u8]),
    /// An ASCII string.
    Text(&'a str),
}

/// Encodes one message (ETG.1020 §13, spec-notes §coe.diag).
fn message(code: u32, kind: u16, text_id: u16, time_ns: u64, params: &[Param<'_>]) -> Vec<u8> {
    let flags = kind | ((params.len() as u16) << 8);
    let mut out = Vec::new();
    out.extend_from_slice(&code.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&text_id.to_le_bytes());
    out.extend_from_slice(&time_ns.to_le_bytes());
    for param in params {
        let (flags, bytes): (u16, Vec<u8>) = match param {
            Param::U16(v) => (0x0006, v.to_le_bytes().to_vec()),
            Param::U32(v) => (0x0007, v.to_le_bytes().to_vec()),
            Param::Bytes(b) => (0x1000 | b.len() as u16, b.to_vec()),
            Param::Text(t) => (0x2000 | t.len() as u16, t.as_bytes().to_vec()),
        };
        out.extend_from_slice(&flags.to_le_bytes());
        out.extend_from_slice(&bytes);
    }
    out
}

fn entry(subindex: u8, data_type: &str, name: &str, value: toml::Value) -> CoeObject {
    CoeObject {
        index: 0x10F3,
        subindex,
        data_type: data_type.into(),
        access: "ro".into(),
        name: name.into(),
        value: Some(value),
        size: None,
    }
}

fn bytes(data: Vec<u8>) -> toml::Value {
    toml::Value::Array(
        data.into_iter()
            .map(|b| toml::Value::Integer(i64::from(b)))
            .collect(),
    )
}

/// The messages of the simulated drive, oldest first (what `ecat diag` must print back).
pub fn drive_messages() -> Vec<Vec<u8>> {
    vec![
        message(0x0000_E001, 0, 0x0101, 1_000_000_000, &[Param::U16(350)]),
        message(
            0x0000_E102,
            1,
            0x0202,
            2_500_000_000,
            &[Param::U32(0x0001_2345), Param::Text("axis 1")],
        ),
        message(
            0x0000_E203,
            2,
            0x0303,
            4_000_000_000,
            &[Param::Bytes(&[0xDE, 0xAD, 0xBE])],
        ),
    ]
}

/// The entries of 0x10F3 for the drive: maximum messages, newest message, newest
/// acknowledged message, new messages available, flags, then the slots (the last unused).
pub fn drive_history() -> Vec<CoeObject> {
    let messages = drive_messages();
    let newest = FIRST_MESSAGE + messages.len() as u8 - 1;
    let mut entries = vec![
        entry(1, "UNSIGNED8", "Maximum Messages", SLOTS.into()),
        entry(2, "UNSIGNED8", "Newest Message", newest.into()),
        entry(3, "UNSIGNED8", "Newest Acknowledged Message", 0.into()),
        entry(
            4,
            "BOOLEAN",
            "New Messages Available",
            toml::Value::Boolean(true),
        ),
        entry(5, "UNSIGNED16", "Flags", 0.into()),
    ];
    for slot in 0..SLOTS {
        // An unused slot reads as a message of zeros (DiagCode 0).
        let data = messages
            .get(usize::from(slot))
            .cloned()
            .unwrap_or_else(|| vec![0; 16]);
        entries.push(entry(
            FIRST_MESSAGE + slot,
            "OCTET_STRING",
            &format!("Diagnosis Message {:03}", slot + 1),
            bytes(data),
        ));
    }
    entries
}
