//! Decoding of the diagnosis history object 0x10F3 (ETG.1020 §13, spec-notes §coe.diag):
//! the header entries and each diagnosis message with its parameters.
//!
//! A message is DiagCode (u32), flags (u16), text ID (u16), time stamp (u64, ns), then the
//! parameters, each its flags (u16) and its bytes; all little-endian. Message flags: type in
//! bits 0-3 (0 info, 1 warning, 2 error), bit 4 a local time stamp (else DC system time),
//! number of parameters in bits 8-15. Parameter flags: kind in bits 12-15 (0 a CoE data type
//! whose index is bits 0-11, 1 a byte array, 2 an ASCII string, 3 a Unicode string, each of
//! bits 0-11 bytes, 4 a text ID).

use master_core::wire::coe::DataType;
use serde_json::{Value, json};

/// Subindex of the first message slot.
pub const FIRST_MESSAGE: u8 = 6;
/// The fixed part of a message.
const HEADER_LEN: usize = 16;

/// One decoded parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    /// `uint16`, `bytes`, `string`, `text_id`, ...
    pub kind: String,
    /// The value as text.
    pub text: String,
}

/// One decoded message.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    /// DiagCode.
    pub code: u32,
    /// The raw flags.
    pub flags: u16,
    /// Text ID.
    pub text_id: u16,
    /// Time stamp, ns.
    pub time_ns: u64,
    /// The parameters, in order.
    pub params: Vec<Param>,
}

impl Message {
    /// Decodes one message slot; `None` for an unused slot (empty, or DiagCode 0 with no
    /// flags), an error for a malformed one.
    pub fn decode(data: &[u8]) -> Result<Option<Message>, String> {
        if data.len() < HEADER_LEN {
            return if data.iter().all(|b| *b == 0) {
                Ok(None)
            } else {
                Err(format!(
                    "a diagnosis message is at least {HEADER_LEN} bytes, got {}",
                    data.len()
                ))
            };
        }
        let u16_at = |at: usize| u16::from_le_bytes([data[at], data[at + 1]]);
        let code = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
        let flags = u16_at(4);
        if code == 0 && flags == 0 {
            return Ok(None);
        }
        let text_id = u16_at(6);
        let mut time = [0; 8];
        time.copy_from_slice(&data[8..16]);
        let count = usize::from(flags >> 8);
        let mut params = Vec::with_capacity(count);
        let mut at = HEADER_LEN;
        for n in 0..count {
            let Some(head) = data.get(at..at + 2) else {
                return Err(format!("parameter {} is missing", n + 1));
            };
            let pflags = u16::from_le_bytes([head[0], head[1]]);
            at += 2;
            let (kind, len) = match pflags >> 12 {
                0 => {
                    let dt = DataType::from(pflags & 0x0FFF);
                    let bits = dt.bit_size().ok_or_else(|| {
                        format!(
                            "parameter {}: data type 0x{:04x} has no fixed size",
                            n + 1,
                            pflags & 0x0FFF
                        )
                    })?;
                    (ParamKind::Typed(dt), (bits as usize).div_ceil(8))
                }
                1 => (ParamKind::Bytes, usize::from(pflags & 0x0FFF)),
                2 => (ParamKind::Ascii, usize::from(pflags & 0x0FFF)),
                3 => (ParamKind::Unicode, usize::from(pflags & 0x0FFF)),
                4 => (ParamKind::TextId, 2),
                other => return Err(format!("parameter {}: unknown kind {other}", n + 1)),
            };
            let Some(bytes) = data.get(at..at + len) else {
                return Err(format!("parameter {} runs past the message", n + 1));
            };
            at += len;
            params.push(kind.show(bytes));
        }
        Ok(Some(Message {
            code,
            flags,
            text_id,
            time_ns: u64::from_le_bytes(time),
            params,
        }))
    }

    /// `info`, `warning`, `error` or `type N`.
    pub fn severity(&self) -> String {
        match self.flags & 0x0F {
            0 => "info".into(),
            1 => "warning".into(),
            2 => "error".into(),
            other => format!("type {other}"),
        }
    }

    /// The time stamp is the slave's local time rather than DC system time.
    pub fn local_time(&self) -> bool {
        self.flags & 0x10 != 0
    }

    /// The `--json` form.
    pub fn json(&self, subindex: u8) -> Value {
        json!({
            "subindex": subindex,
            "code": self.code,
            "type": self.severity(),
            "flags": self.flags,
            "text_id": self.text_id,
            "timestamp_ns": self.time_ns,
            "local_time": self.local_time(),
            "parameters": self.params.iter()
                .map(|p| json!({"kind": p.kind, "value": p.text}))
                .collect::<Vec<_>>(),
        })
    }
}

enum ParamKind {
    Typed(DataType),
    Bytes,
    Ascii,
    Unicode,
    TextId,
}

impl ParamKind {
    fn show(self, bytes: &[u8]) -> Param {
        let mut wide = [0u8; 8];
        let n = bytes.len().min(8);
        wide[..n].copy_from_slice(&bytes[..n]);
        let unsigned = u64::from_le_bytes(wide);
        let (kind, text) = match self {
            ParamKind::Typed(dt) => {
                let text = match dt {
                    DataType::Real32 => {
                        f32::from_le_bytes(wide[..4].try_into().unwrap_or_default()).to_string()
                    }
                    DataType::Real64 => f64::from_le_bytes(wide).to_string(),
                    DataType::Integer8
                    | DataType::Integer16
                    | DataType::Integer32
                    | DataType::Integer64 => {
                        // Sign-extend from the parameter's width.
                        let shift = 64 - 8 * n as u32;
                        (((unsigned << shift) as i64) >> shift).to_string()
                    }
                    _ => format!("{unsigned} (0x{unsigned:x})"),
                };
                (dt.name().to_ascii_lowercase(), text)
            }
            ParamKind::Bytes => ("bytes".into(), hex::encode(bytes)),
            ParamKind::Ascii => (
                "string".into(),
                format!("{:?}", String::from_utf8_lossy(bytes)),
            ),
            ParamKind::Unicode => {
                let units: Vec<u16> = bytes
                    .chunks_exact(2)
                    .map(|c| u16::from_le_bytes([c[0], c[1]]))
                    .collect();
                (
                    "unicode_string".into(),
                    format!("{:?}", String::from_utf16_lossy(&units)),
                )
            }
            ParamKind::TextId => ("text_id".into(), format!("0x{unsigned:04x}")),
        };
        Param { kind, text }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_with_each_kind_of_parameter_decodes() {
        let mut m = Vec::new();
        m.extend_from_slice(&0x0000_E102u32.to_le_bytes());
        m.extend_from_slice(&(0x0401u16).to_le_bytes()); // warning, 4 parameters
        m.extend_from_slice(&0x0202u16.to_le_bytes());
        m.extend_from_slice(&2_500_000_000u64.to_le_bytes());
        m.extend_from_slice(&0x0007u16.to_le_bytes());
        m.extend_from_slice(&0x12345u32.to_le_bytes());
        m.extend_from_slice(&0x2002u16.to_le_bytes());
        m.extend_from_slice(b"ab");
        m.extend_from_slice(&0x1001u16.to_le_bytes());
        m.push(0xFE);
        m.extend_from_slice(&0x0003u16.to_le_bytes()); // INTEGER16
        m.extend_from_slice(&(-5i16).to_le_bytes());
        let d = Message::decode(&m).unwrap().unwrap();
        assert_eq!(
            (d.code, d.text_id, d.time_ns),
            (0xE102, 0x0202, 2_500_000_000)
        );
        assert_eq!(d.severity(), "warning");
        let texts: Vec<_> = d.params.iter().map(|p| p.text.as_str()).collect();
        assert_eq!(texts, ["74565 (0x12345)", "\"ab\"", "fe", "-5"]);
    }

    #[test]
    fn unused_slots_and_truncated_messages() {
        assert_eq!(Message::decode(&[0; 16]).unwrap(), None);
        assert_eq!(Message::decode(&[]).unwrap(), None);
        assert!(Message::decode(&[1, 0, 0]).is_err());
        let mut m = vec![1, 0, 0, 0, 0x00, 0x01, 0, 0];
        m.extend_from_slice(&[0; 8]);
        m.extend_from_slice(&0x1004u16.to_le_bytes());
        m.push(1);
        assert!(Message::decode(&m).unwrap_err().contains("runs past"));
    }
}
