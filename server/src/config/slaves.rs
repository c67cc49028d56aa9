//! `[[slave]]`: the expected topology and what each slave gets at every bring-up: its
//! PDO assignment and mapping (0x1C12/0x1C13, 0x16xx/0x1Axx; ETG.1000.6 §5.6.7.4.7-8),
//! its distributed clocks (SYNC0/SYNC1 or off), and its start-up commands (CoE SDO
//! downloads and SoE IDN writes, each tied to an AL transition; ETG.1020 §6.4).

use std::time::Duration;

use serde::{Deserialize, Serialize};

use master_core::master::{
    ExpectedIdentity, PdoAssignment, PdoEntryInfo, PdoMapping, RevisionMatch, SlaveAddress,
    SlaveConfig, SlaveDc, StartupAction, StartupCommand, SyncSignal, Transition,
};

use super::duration;

/// How the found revision is compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum RevisionCompare {
    /// Equal.
    #[default]
    Exact,
    /// At least.
    Minimum,
}

/// `[slave.dc]`: SYNC0 (and SYNC1) of this slave, or DC off.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DcEntry {
    /// `false`: no SYNC signals on this slave.
    #[serde(default = "yes")]
    pub enabled: bool,
    /// SYNC0 cycle (needed when enabled).
    #[serde(default, with = "duration", skip_serializing_if = "Option::is_none")]
    pub sync0_cycle: Option<Duration>,
    /// SYNC0 shift from a multiple of the cycle.
    #[serde(default, with = "duration", skip_serializing_if = "Option::is_none")]
    pub sync0_shift: Option<Duration>,
    /// SYNC1 cycle; absent: no SYNC1.
    #[serde(default, with = "duration", skip_serializing_if = "Option::is_none")]
    pub sync1_cycle: Option<Duration>,
    /// SYNC1 shift.
    #[serde(default, with = "duration", skip_serializing_if = "Option::is_none")]
    pub sync1_shift: Option<Duration>,
}

fn yes() -> bool {
    true
}

/// One mapped object in a PDO: `{ index = 0x6040, subindex = 0, bits = 16 }` (index 0 is
/// a gap of `bits`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EntryEntry {
    /// Object index.
    pub index: u16,
    /// Subindex.
    #[serde(default)]
    pub subindex: u8,
    /// Bit length.
    pub bits: u8,
}

/// One PDO of an assignment: its index and, to rewrite its mapping, its entries.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdoEntry {
    /// 0x1600.. (outputs) or 0x1A00.. (inputs).
    pub index: u16,
    /// The mapping to write; absent: the slave's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub entries: Option<Vec<EntryEntry>>,
}

/// `[[slave.pdo_assign]]`: the PDOs of one SyncManager.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AssignEntry {
    /// SyncManager (2: outputs, 0x1C12; 3: inputs, 0x1C13).
    pub sm: u8,
    /// The PDOs, in image order.
    pub pdos: Vec<PdoEntry>,
}

/// An IDN: a number or the usual text (`"S-0-0032"`, `"P-0-0005"`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum IdnText {
    /// The 16-bit number.
    Number(u16),
    /// `S-x-yyyy` or `P-x-yyyy`.
    Text(String),
}

/// `[[slave.startup]]`: one start-up command. Either a CoE SDO download (`index`,
/// `subindex`) or an SoE IDN write (`idn`, `drive`); the value as `value` with `type`
/// (u8 u16 u32 u64 i8 i16 i32 i64) or as `data` (hex bytes).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartupEntry {
    /// The transition: `IP`, `PS`, `SO`, `SP`, `OS`, `OP`, `PI`, `SI`, `OI`.
    pub transition: String,
    /// CoE object index.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index: Option<u16>,
    /// CoE subindex (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subindex: Option<u8>,
    /// Write the object by complete access.
    #[serde(default, skip_serializing_if = "is_false")]
    pub complete_access: bool,
    /// SoE IDN.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub idn: Option<IdnText>,
    /// SoE drive number (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<u8>,
    /// The value, with `type`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<i64>,
    /// The type of `value`.
    #[serde(default, rename = "type", skip_serializing_if = "Option::is_none")]
    pub data_type: Option<String>,
    /// The value as hex bytes, as sent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<String>,
    /// A note.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub comment: Option<String>,
}

fn is_false(b: &bool) -> bool {
    !b
}

/// `[[slave]]`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SlaveEntry {
    /// A label for messages.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Ring position (0: first).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<u16>,
    /// Station alias.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alias: Option<u16>,
    /// Station address.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub station: Option<u16>,
    /// Expected vendor ID.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vendor_id: Option<u32>,
    /// Expected product code.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub product_code: Option<u32>,
    /// Expected revision.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub revision: Option<u32>,
    /// `exact` or `minimum`.
    #[serde(default)]
    pub revision_match: RevisionCompare,
    /// Distributed clocks; absent: the master's defaults (no SYNC0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dc: Option<DcEntry>,
    /// PDO assignment, per SyncManager.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pdo_assign: Vec<AssignEntry>,
    /// Start-up commands, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub startup: Vec<StartupEntry>,
}

/// What one entry becomes for the master.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveSetup {
    /// Identity check, start-up commands, DC.
    pub config: SlaveConfig,
    /// The PDO assignment, if any.
    pub pdos: Vec<PdoAssignment>,
}

impl SlaveEntry {
    /// How messages name this entry: `[[slave]] #2 (position 1, "drive")`.
    pub fn label(&self, number: usize) -> String {
        let at = match (self.position, self.alias, self.station) {
            (Some(p), _, _) => format!("position {p}"),
            (_, Some(a), _) => format!("alias {a}"),
            (_, _, Some(s)) => format!("station {s}"),
            _ => "no address".into(),
        };
        match &self.name {
            Some(name) => format!("[[slave]] #{number} ({at}, {name:?})"),
            None => format!("[[slave]] #{number} ({at})"),
        }
    }

    /// The slave this entry names.
    pub fn address(&self) -> Result<SlaveAddress, String> {
        match (self.position, self.alias, self.station) {
            (Some(p), None, None) => Ok(SlaveAddress::Position(p)),
            (None, Some(0), None) => Err("alias 0 names no slave".into()),
            (None, Some(a), None) => Ok(SlaveAddress::Alias(a)),
            (None, None, Some(s)) => Ok(SlaveAddress::Station(s)),
            (None, None, None) => Err("needs one of position, alias or station".into()),
            _ => Err("give only one of position, alias or station".into()),
        }
    }

    /// The master's view of this entry, checked; `cycle` is the bus cycle.
    pub fn setup(&self) -> Result<SlaveSetup, String> {
        let address = self.address()?;
        let expected =
            (self.vendor_id.is_some() || self.product_code.is_some() || self.revision.is_some())
                .then_some(ExpectedIdentity {
                    vendor_id: self.vendor_id,
                    product_code: self.product_code,
                    revision: self.revision,
                    revision_match: match self.revision_match {
                        RevisionCompare::Exact => RevisionMatch::Exact,
                        RevisionCompare::Minimum => RevisionMatch::Minimum,
                    },
                });
        let dc = self.dc.as_ref().map(DcEntry::slave_dc).transpose()?;
        let startup = self
            .startup
            .iter()
            .enumerate()
            .map(|(i, s)| {
                s.command()
                    .map_err(|err| format!("startup #{}: {err}", i + 1))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut pdos = Vec::new();
        for (i, assign) in self.pdo_assign.iter().enumerate() {
            pdos.push(
                assign
                    .assignment()
                    .map_err(|err| format!("pdo_assign #{}: {err}", i + 1))?,
            );
        }
        Ok(SlaveSetup {
            config: SlaveConfig {
                address: Some(address),
                expected,
                startup,
                dc,
            },
            pdos,
        })
    }
}

impl DcEntry {
    fn slave_dc(&self) -> Result<SlaveDc, String> {
        if !self.enabled {
            return Ok(SlaveDc::Off);
        }
        let cycle = self
            .sync0_cycle
            .ok_or("dc: sync0_cycle is needed (or enabled = false)")?;
        if cycle.is_zero() || duration::nanos(cycle) > u64::from(u32::MAX) {
            return Err(format!(
                "dc: sync0_cycle {:?} must be more than 0 and at most 4.29 s",
                duration::show(cycle)
            ));
        }
        let sync1 = self.sync1_cycle.map(|cycle| SyncSignal {
            cycle,
            shift: self.sync1_shift.unwrap_or_default(),
        });
        Ok(SlaveDc::Sync {
            sync0: SyncSignal {
                cycle,
                shift: self.sync0_shift.unwrap_or_default(),
            },
            sync1,
        })
    }
}

impl AssignEntry {
    fn assignment(&self) -> Result<PdoAssignment, String> {
        let range = match self.sm {
            2 => 0x1600..=0x17FF,
            3 => 0x1A00..=0x1BFF,
            other => {
                return Err(format!(
                    "sm = {other}: only SyncManagers 2 (outputs) and 3 (inputs) are assigned"
                ));
            }
        };
        let mut pdos = Vec::new();
        for pdo in &self.pdos {
            if !range.contains(&pdo.index) {
                return Err(format!(
                    "PDO {:#06x} cannot be assigned to SM{} (its PDOs are {:#06x}-{:#06x})",
                    pdo.index,
                    self.sm,
                    range.start(),
                    range.end()
                ));
            }
            pdos.push(PdoMapping {
                index: pdo.index,
                entries: pdo.entries.as_ref().map(|entries| {
                    entries
                        .iter()
                        .map(|e| PdoEntryInfo::new(e.index, e.subindex, e.bits))
                        .collect()
                }),
            });
        }
        Ok(PdoAssignment {
            sync_manager: self.sm,
            pdos,
        })
    }
}

impl StartupEntry {
    /// The command, checked.
    pub fn command(&self) -> Result<StartupCommand, String> {
        let transition = Transition::from_code(&self.transition).ok_or_else(|| {
            format!(
                "transition {:?} is not one of IP, PS, SO, SP, OS, OP, PI, SI, OI",
                self.transition
            )
        })?;
        let data = self.bytes()?;
        let action = match (self.index, &self.idn) {
            (Some(index), None) => {
                if self.drive.is_some() {
                    return Err("drive is for SoE (idn) commands".into());
                }
                StartupAction::Sdo {
                    index,
                    subindex: self.subindex.unwrap_or(0),
                    data,
                    complete_access: self.complete_access,
                }
            }
            (None, Some(idn)) => {
                if self.subindex.is_some() || self.complete_access {
                    return Err("subindex and complete_access are for CoE (index) commands".into());
                }
                let idn = match idn {
                    IdnText::Number(n) => *n,
                    IdnText::Text(text) => text
                        .parse::<master_core::wire::soe::Idn>()
                        .map(u16::from)
                        .map_err(|err| format!("idn {text:?}: {err}"))?,
                };
                let drive = self.drive.unwrap_or(0);
                if drive > 7 {
                    return Err(format!("drive {drive}: drives are 0 to 7"));
                }
                StartupAction::Idn { drive, idn, data }
            }
            (None, None) => return Err("needs index (CoE) or idn (SoE)".into()),
            (Some(_), Some(_)) => return Err("give index (CoE) or idn (SoE), not both".into()),
        };
        Ok(StartupCommand { transition, action })
    }

    /// The bytes to send: `value` as `type`, little-endian, or `data`.
    fn bytes(&self) -> Result<Vec<u8>, String> {
        match (&self.data, self.value, &self.data_type) {
            (Some(hex_text), None, None) => {
                let clean: String = hex_text.chars().filter(|c| !c.is_whitespace()).collect();
                let bytes = hex::decode(clean.trim_start_matches("0x"))
                    .map_err(|err| format!("data {hex_text:?} is not hex bytes: {err}"))?;
                if bytes.is_empty() {
                    return Err("data is empty".into());
                }
                Ok(bytes)
            }
            (None, Some(value), Some(ty)) => typed(value, ty),
            (None, Some(_), None) => {
                Err("value needs a type (u8 u16 u32 u64 i8 i16 i32 i64)".into())
            }
            (None, None, _) => Err("needs value (with type) or data".into()),
            (Some(_), _, _) => Err("give value (with type) or data, not both".into()),
        }
    }
}

/// `value` as the integer type named `ty`, little-endian.
fn typed(value: i64, ty: &str) -> Result<Vec<u8>, String> {
    let wide = i128::from(value);
    let (len, signed) = match ty {
        "u8" => (1, false),
        "u16" => (2, false),
        "u32" => (4, false),
        "u64" => (8, false),
        "i8" => (1, true),
        "i16" => (2, true),
        "i32" => (4, true),
        "i64" => (8, true),
        other => {
            return Err(format!(
                "type {other:?} is not one of u8 u16 u32 u64 i8 i16 i32 i64"
            ));
        }
    };
    let bits = 8 * len as u32;
    let (min, max) = if signed {
        (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
    } else {
        (0, (1i128 << bits) - 1)
    };
    if wide < min || wide > max {
        return Err(format!("value {value} does not fit type {ty}"));
    }
    Ok(value.to_le_bytes()[..len].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(text: &str) -> Result<SlaveEntry, toml::de::Error> {
        toml::from_str(text)
    }

    #[test]
    fn a_drive_entry_becomes_the_master_s_configuration() {
        let e = entry(
            r#"
            position = 0
            product_code = 1
            revision = 0x10000
            revision_match = "minimum"
            dc = { sync0_cycle = "500us" }
            pdo_assign = [
              { sm = 2, pdos = [{ index = 0x1600, entries = [{ index = 0x6040, bits = 16 }] }] },
            ]
            [[startup]]
            transition = "PS"
            index = 0x6060
            value = 8
            type = "i8"
            [[startup]]
            transition = "so"
            idn = "S-0-0032"
            data = "0200"
            "#,
        )
        .unwrap();
        let setup = e.setup().unwrap();
        assert_eq!(setup.config.address, Some(SlaveAddress::Position(0)));
        assert_eq!(
            setup.config.expected.unwrap().revision_match,
            RevisionMatch::Minimum
        );
        assert_eq!(
            setup.config.dc,
            Some(SlaveDc::Sync {
                sync0: SyncSignal {
                    cycle: Duration::from_micros(500),
                    shift: Duration::ZERO
                },
                sync1: None
            })
        );
        assert_eq!(
            setup.config.startup[0].action,
            StartupAction::Sdo {
                index: 0x6060,
                subindex: 0,
                data: vec![8],
                complete_access: false
            }
        );
        assert_eq!(setup.config.startup[1].transition, Transition::SAFEOP_OP);
        assert_eq!(
            setup.config.startup[1].action,
            StartupAction::Idn {
                drive: 0,
                idn: 32,
                data: vec![2, 0]
            }
        );
        assert_eq!(setup.pdos[0].pdos[0].index, 0x1600);
    }

    #[test]
    fn bad_entries_say_what_is_wrong() {
        assert!(
            entry("position = 0\nprodukt = 1")
                .unwrap_err()
                .to_string()
                .contains("produkt")
        );
        assert!(entry("position = \"zero\"").is_err());
        let both = entry("position = 0\nalias = 3").unwrap();
        assert!(both.setup().unwrap_err().contains("only one"));
        let big = entry("position = 0\n[[startup]]\ntransition = \"PS\"\nindex = 0x6060\nvalue = 300\ntype = \"u8\"").unwrap();
        assert_eq!(
            big.setup().unwrap_err(),
            "startup #1: value 300 does not fit type u8"
        );
        let wrong_sm =
            entry("position = 0\npdo_assign = [{ sm = 2, pdos = [{ index = 0x1A00 }] }]").unwrap();
        assert!(wrong_sm.setup().unwrap_err().contains("0x1a00"));
        let no_transition =
            entry("position = 0\n[[startup]]\ntransition = \"XY\"\nindex = 1\ndata = \"00\"")
                .unwrap();
        assert!(no_transition.setup().unwrap_err().contains("\"XY\""));
    }
}
