//! A `[[watch]]` entry of the configuration and what it resolves to.

use master_core::wire::soe::Idn;
use serde::{Deserialize, Serialize};

use crate::input::address::parse_name;
use crate::input::value::ValueType;

/// The most watches one configuration may list (one task each).
pub const MAX_WATCHES: usize = 256;
/// Shortest period accepted.
pub const MIN_PERIOD_MS: u64 = 10;
/// Longest period accepted (a day).
pub const MAX_PERIOD_MS: u64 = 86_400_000;

fn default_period() -> u64 {
    1000
}

fn is_zero(drive: &u8) -> bool {
    *drive == 0
}

/// One watched value (`[[watch]]`): a CoE object entry or an SoE IDN of a slave, read every
/// `period_ms` and exported as the gauge `ecat_watch_value`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WatchSpec {
    /// The slave, in the common syntax (`3`, `pos:3`, `station:1004`, `alias:0x777+2`).
    pub slave: String,
    /// A CoE entry, `index:subindex`, both hex (`"0x6041:00"`, `"1018:02"`): the form of
    /// earlier releases, kept. New configurations use `index` and `subindex`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sdo: Option<String>,
    /// A CoE entry's index in the one number syntax: a TOML integer (`0x6041`) or a string
    /// (`"0x6041"`, `"24641"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index: Option<Number>,
    /// The entry's subindex with `index` (default 0), in the same syntax.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subindex: Option<Number>,
    /// An SoE IDN (`"S-0-0051"`, `"P-0-0100"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub idn: Option<String>,
    /// A process-data entry, `index:subindex` in hex (`"0x6064:0"`): read from the last
    /// cycle's image when Prometheus scrapes, with no mailbox traffic (`period_ms` and
    /// `type` do not apply: the entry's own type decodes it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pdo: Option<String>,
    /// The SoE drive number (IDNs only).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub drive: u8,
    /// How often to read it, in milliseconds (default 1000).
    #[serde(default = "default_period")]
    pub period_ms: u64,
    /// The value type (`u8` … `u64`, `i8` … `i64`, `f32`, `f64`, `bool`); absent: for CoE
    /// the type the slave's SDO Information names, for SoE an unsigned little-endian number
    /// of the length read.
    #[serde(default, rename = "type", skip_serializing_if = "Option::is_none")]
    pub value_type: Option<String>,
    /// The `name` label (default empty).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A number in a `[[watch]]` entry: a TOML integer, or a string in the one number syntax
/// (decimal or `0x` hex).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Number {
    /// A TOML integer (TOML itself reads `0x6041`).
    Int(u64),
    /// Decimal or `0x` hex text.
    Text(String),
}

impl Number {
    fn value<T: TryFrom<u64>>(&self, field: &str) -> Result<T, String> {
        match self {
            Number::Int(n) => {
                T::try_from(*n).map_err(|_| format!("watch {field} {n} out of range"))
            }
            Number::Text(text) => crate::input::value::parse_number(text, field)
                .map_err(|err| format!("watch {field}: {err}")),
        }
    }
}

/// What a watch reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// CoE entry.
    Sdo {
        /// Index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// A process-data entry, read from the image at scrape time.
    Pdo {
        /// Index.
        index: u16,
        /// Subindex.
        subindex: u8,
    },
    /// SoE IDN of a drive.
    Idn {
        /// Drive number.
        drive: u8,
        /// The IDN.
        idn: Idn,
    },
}

impl Target {
    /// The `object` label: `0x6041:00` or `S-0-0051`.
    pub fn label(&self) -> String {
        match self {
            Target::Sdo { index, subindex } | Target::Pdo { index, subindex } => {
                format!("{index:#06x}:{subindex:02x}")
            }
            Target::Idn { idn, .. } => idn.to_string(),
        }
    }
}

/// `index:subindex`, both hex.
fn hex_pair(text: &str) -> Option<(u16, u8)> {
    let (index, subindex) = text.split_once(':')?;
    let index = hex_number(index).and_then(|i| u16::try_from(i).ok())?;
    let subindex = hex_number(subindex).and_then(|s| u8::try_from(s).ok())?;
    Some((index, subindex))
}

fn hex_number(text: &str) -> Option<u32> {
    let digits = text
        .trim()
        .strip_prefix("0x")
        .or_else(|| text.trim().strip_prefix("0X"))
        .unwrap_or(text.trim());
    u32::from_str_radix(digits, 16).ok()
}

impl WatchSpec {
    /// What it reads; an error names what is wrong.
    pub fn target(&self) -> Result<Target, String> {
        if let Some(pdo) = &self.pdo {
            if self.sdo.is_some() || self.idn.is_some() || self.index.is_some() {
                return Err(format!(
                    "watch on slave {:?}: give exactly one of pdo, sdo, index and idn",
                    self.slave
                ));
            }
            let (index, subindex) = hex_pair(pdo)
                .ok_or_else(|| format!("watch pdo {pdo:?}: expected index:subindex in hex"))?;
            return Ok(Target::Pdo { index, subindex });
        }
        if let Some(index) = &self.index {
            if self.sdo.is_some() || self.idn.is_some() {
                return Err(format!(
                    "watch on slave {:?}: give exactly one of sdo, index and idn",
                    self.slave
                ));
            }
            return Ok(Target::Sdo {
                index: index.value("index")?,
                subindex: match &self.subindex {
                    Some(sub) => sub.value("subindex")?,
                    None => 0,
                },
            });
        }
        if self.subindex.is_some() {
            return Err(format!(
                "watch on slave {:?}: subindex without index",
                self.slave
            ));
        }
        match (&self.sdo, &self.idn) {
            (Some(sdo), None) => {
                let (index, subindex) = hex_pair(sdo)
                    .ok_or_else(|| format!("watch sdo {sdo:?}: expected index:subindex in hex"))?;
                Ok(Target::Sdo { index, subindex })
            }
            (None, Some(idn)) => Ok(Target::Idn {
                drive: self.drive,
                idn: idn
                    .parse()
                    .map_err(|err| format!("watch idn {idn:?}: {err}"))?,
            }),
            _ => Err(format!(
                "watch on slave {:?}: give exactly one of sdo and idn",
                self.slave
            )),
        }
    }

    /// The value type named, if any; strings and raw bytes are no gauge values.
    pub fn value_type(&self) -> Result<Option<ValueType>, String> {
        let Some(name) = &self.value_type else {
            return Ok(None);
        };
        let ty: ValueType = name
            .parse()
            .map_err(|err| format!("watch type {name:?}: {err}"))?;
        if matches!(ty, ValueType::String | ValueType::Hex) {
            return Err(format!("watch type {name:?}: not a number"));
        }
        Ok(Some(ty))
    }

    /// Checks everything a watch needs before ecatd starts.
    pub fn check(&self) -> Result<(), String> {
        parse_name(&self.slave).map_err(|err| format!("watch slave {:?}: {err}", self.slave))?;
        self.target()?;
        self.value_type()?;
        if !(MIN_PERIOD_MS..=MAX_PERIOD_MS).contains(&self.period_ms) {
            return Err(format!(
                "watch period_ms {} outside {MIN_PERIOD_MS}..={MAX_PERIOD_MS}",
                self.period_ms
            ));
        }
        Ok(())
    }
}

/// Checks a whole `[[watch]]` list.
pub fn check_all(watches: &[WatchSpec]) -> Result<(), String> {
    if watches.len() > MAX_WATCHES {
        return Err(format!("more than {MAX_WATCHES} watches"));
    }
    watches.iter().try_for_each(WatchSpec::check)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> WatchSpec {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn targets_parse_and_label_canonically() {
        let sdo = spec("slave = \"3\"\nsdo = \"6041:0\"");
        assert_eq!(
            sdo.target(),
            Ok(Target::Sdo {
                index: 0x6041,
                subindex: 0
            })
        );
        assert_eq!(sdo.target().unwrap().label(), "0x6041:00");
        assert_eq!(sdo.period_ms, 1000);
        let pdo = spec("slave = \"0\"\npdo = \"0x6064:0\"");
        assert_eq!(
            pdo.target(),
            Ok(Target::Pdo {
                index: 0x6064,
                subindex: 0
            })
        );
        assert_eq!(pdo.target().unwrap().label(), "0x6064:00");
        let idn = spec("slave = \"#1001\"\nidn = \"P-0-100\"\ntype = \"u16\"\nperiod_ms = 50");
        assert_eq!(idn.target().unwrap().label(), "P-0-0100");
        assert_eq!(idn.value_type(), Ok(Some(ValueType::U16)));
        assert!(idn.check().is_ok());
        // The one number syntax: TOML integers (decimal or 0x) or strings; prefixed slaves.
        for text in [
            "slave = \"pos:3\"\nindex = 0x6041\nsubindex = 0",
            "slave = \"station:1004\"\nindex = 24641",
            "slave = \"alias:0x777+2\"\nindex = \"0x6041\"\nsubindex = \"0\"",
        ] {
            let s = spec(text);
            assert_eq!(s.target().unwrap().label(), "0x6041:00", "{text}");
            assert!(s.check().is_ok(), "{text}");
        }
    }

    #[test]
    fn bad_watches_are_refused() {
        for text in [
            "slave = \"3\"",
            "slave = \"3\"\nsdo = \"0x6041:00\"\nidn = \"S-0-0051\"",
            "slave = \"3\"\nsdo = \"0x6041\"",
            "slave = \"3\"\nsdo = \"0x16041:00\"",
            "slave = \"3\"\nidn = \"X-0-1\"",
            "slave = \"three\"\nsdo = \"0x6041:00\"",
            "slave = \"3\"\nsdo = \"0x6041:00\"\nperiod_ms = 1",
            "slave = \"3\"\nsdo = \"0x6041:00\"\ntype = \"string\"",
            "slave = \"3\"\nindex = 0x16041",
            "slave = \"3\"\nindex = \"6041h\"",
            "slave = \"3\"\nindex = 0x6041\nsdo = \"0x6041:00\"",
            "slave = \"3\"\nsubindex = 1\nsdo = \"0x6041:00\"",
            "slave = \"3\"\npdo = \"0x6064\"",
            "slave = \"3\"\npdo = \"0x6064:0\"\nsdo = \"0x6064:00\"",
        ] {
            assert!(spec(text).check().is_err(), "{text}");
        }
        assert!(toml::from_str::<WatchSpec>("slave = \"3\"\nsdo = \"1:0\"\nperiod = 5").is_err());
    }
}
