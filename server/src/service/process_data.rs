//! Process data for the APIs: the layout every attached control program gets (the same
//! entries as the application interface's shared image, docs/application.md) and the values
//! of the last completed cycle, decoded by type. Values come from the master's snapshot of
//! that cycle: reading them sends no frame.

use ecat_app::entry::Entry;
use master_core::master::SlaveAddress;
use master_core::wire::coe::DataType;

use super::{ApiError, Core, Operation, Result, SlaveName, Ticket};

/// One mapped entry and where it sits in the image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdEntryView {
    /// Ring position of its slave.
    pub slave: u16,
    /// The slave's station address.
    pub station: u16,
    /// The PDO mapping it.
    pub pdo: u16,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Its name (SII).
    pub name: String,
    /// Its CoE data type's name (`UNSIGNED16`), empty when not known.
    pub data_type: String,
    /// First bit in the image.
    pub bit_offset: u32,
    /// Bits it takes.
    pub bit_length: u16,
    /// `in` (slave to master) or `out`.
    pub direction: &'static str,
}

impl From<&Entry> for PdEntryView {
    fn from(e: &Entry) -> PdEntryView {
        PdEntryView {
            slave: e.position,
            station: e.station,
            pdo: e.pdo,
            index: e.index,
            subindex: e.subindex,
            name: e.name.clone(),
            data_type: match e.data_type {
                0 => String::new(),
                code => DataType::from(code).to_string(),
            },
            bit_offset: e.bit_offset,
            bit_length: e.bit_length,
            direction: e.direction.as_str(),
        }
    }
}

/// The layout of the process image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LayoutView {
    /// The application interface's layout generation (0 when it does not serve).
    pub generation: u32,
    /// Bytes of the image.
    pub image_len: usize,
    /// The cycle period in ns.
    pub period_ns: u64,
    /// Every entry, slave by slave (outputs first within a slave).
    pub entries: Vec<PdEntryView>,
}

impl Core {
    /// The process image's layout: every mapped entry with its place, as an attached
    /// program gets it.
    pub fn process_data_layout(&self, slave: Option<SlaveName>) -> Result<LayoutView> {
        let only = slave.map(|s| self.position_of(s)).transpose()?;
        let (entries, image_len) = crate::app::layout_entries(&self.master);
        Ok(LayoutView {
            generation: self.app_status().map_or(0, |s| s.generation),
            image_len,
            period_ns: u64::try_from(self.master.cycle_timing().period.as_nanos())
                .unwrap_or(u64::MAX),
            entries: entries
                .iter()
                .filter(|e| only.is_none_or(|p| e.position == p))
                .map(PdEntryView::from)
                .collect(),
        })
    }

    /// The ring position of the slave `slave` names.
    fn position_of(&self, slave: SlaveName) -> Result<u16> {
        let address: SlaveAddress = self.address(slave)?;
        self.master
            .slave(address)
            .map(|s| s.position)
            .map_err(Into::into)
    }
}

/// A value decoded by its entry's type.
#[derive(Debug, Clone, PartialEq)]
pub enum PdValue {
    /// A 1-bit entry or a BOOLEAN.
    Bool(bool),
    /// A signed integer type.
    Int(i64),
    /// An unsigned integer type, or one of no known type up to 64 bits.
    Uint(u64),
    /// REAL32 or REAL64.
    Real(f64),
    /// Anything else, as hex (strings, octet strings, entries over 64 bits).
    Hex(String),
}

/// A value asked to be written into an output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PdInput {
    /// An integer (booleans as 0 and 1).
    Int(i64),
    /// A floating-point number (REAL32, REAL64 entries).
    Real(f64),
}

/// An output forced from an API.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceView {
    /// The entry.
    pub entry: PdEntryView,
    /// The value it is forced to.
    pub value: PdValue,
    /// Who forced it.
    pub by: String,
    /// Whether it was forced over an application's outputs.
    pub over_owner: bool,
    /// When, seconds since the Unix epoch.
    pub since: u64,
}

/// One entry with its value in a cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct PdValueView {
    /// The entry.
    pub entry: PdEntryView,
    /// Its value: an input as the cycle received it, an output as the cycle sent it.
    pub value: PdValue,
    /// Its bytes (the entry's bits from bit 0, little-endian).
    pub raw: Vec<u8>,
    /// Who forced it, if it is forced.
    pub forced_by: Option<String>,
}

/// The values of one completed cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessDataView {
    /// The cycle the values belong to.
    pub cycle: u64,
    /// Its working counter.
    pub wkc: u16,
    /// The working counter it should have had.
    pub expected_wkc: u16,
    /// The entries and values.
    pub values: Vec<PdValueView>,
}

/// The bits of `entry` in `image`, from bit 0 of the first byte.
fn raw_bits(entry: &Entry, image: &[u8]) -> Vec<u8> {
    let bits = usize::from(entry.bit_length);
    let mut out = vec![0u8; bits.div_ceil(8)];
    if !entry.lies_in(image.len()) {
        return out;
    }
    for i in 0..bits {
        let at = entry.bit_offset as usize + i;
        if image[at / 8] & (1 << (at % 8)) != 0 {
            out[i / 8] |= 1 << (i % 8);
        }
    }
    out
}

/// The value of `entry` from its raw bits, decoded by its type.
pub fn decode(entry: &Entry, raw: &[u8]) -> PdValue {
    let bits = entry.bit_length;
    let wide = |raw: &[u8]| {
        let mut bytes = [0u8; 8];
        bytes[..raw.len().min(8)].copy_from_slice(&raw[..raw.len().min(8)]);
        u64::from_le_bytes(bytes)
    };
    match (entry.data_type, bits) {
        (0x0001, _) | (0, 1) => PdValue::Bool(raw.first().is_some_and(|b| b & 1 != 0)),
        (0x0008, 32) => PdValue::Real(f64::from(f32::from_bits(wide(raw) as u32))),
        (0x0011, 64) => PdValue::Real(f64::from_bits(wide(raw))),
        (_, 1..=64) if entry.is_signed() => {
            let image = {
                let mut b = raw.to_vec();
                b.resize(8, 0);
                b
            };
            let probe = Entry {
                bit_offset: 0,
                ..entry.clone()
            };
            PdValue::Int(probe.get_i64(&image))
        }
        (0 | 0x0005..=0x0007 | 0x0016 | 0x0018..=0x001B, 1..=64) => PdValue::Uint(wide(raw)),
        _ => PdValue::Hex(hex::encode(raw)),
    }
}

impl Core {
    /// The values of the last completed cycle, of every slave or of `slave`.
    pub fn process_data(&self, slave: Option<SlaveName>) -> Result<ProcessDataView> {
        let only = slave.map(|s| self.position_of(s)).transpose()?;
        let (entries, _) = crate::app::layout_entries(&self.master);
        let forces = self.app.get().map(|a| a.forces()).unwrap_or_default();
        let snapshot = self.master.snapshot();
        let values = entries
            .iter()
            .filter(|e| only.is_none_or(|p| e.position == p))
            .map(|e| {
                let image = match e.direction {
                    ecat_app::Direction::In => &snapshot.inputs,
                    ecat_app::Direction::Out => &snapshot.outputs,
                };
                let raw = raw_bits(e, image);
                PdValueView {
                    entry: PdEntryView::from(e),
                    value: decode(e, &raw),
                    raw,
                    forced_by: forces.iter().find(|f| &f.entry == e).map(|f| f.by.clone()),
                }
            })
            .collect();
        Ok(ProcessDataView {
            cycle: snapshot.cycle,
            wkc: snapshot.wkc,
            expected_wkc: snapshot.expected_wkc,
            values,
        })
    }

    /// The entry `index:subindex` of `slave` in the current layout.
    fn pd_entry(&self, slave: SlaveName, index: u16, subindex: u8) -> Result<Entry> {
        let position = self.position_of(slave)?;
        let app = self.app.get().ok_or_else(|| {
            ApiError::unavailable(
                "the application interface is not running: nothing can force outputs",
            )
        })?;
        app.entries()
            .into_iter()
            .find(|e| e.position == position && e.index == index && e.subindex == subindex)
            .ok_or_else(|| {
                ApiError::unknown_entry(format!(
                    "slave {slave} maps no process-data entry 0x{index:04X}:{subindex:02X}"
                ))
            })
    }

    /// Forces output `index:subindex` of `slave` to `value` from the next cycle on, for
    /// `caller`. Refused (409 `outputs_owned`) while an application owns the outputs,
    /// unless `over_owner`; the audit line says so.
    pub fn force_output(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        value: PdInput,
        over_owner: bool,
    ) -> Result<ForceView> {
        // The audit line says when the force went over an owner.
        ticket.check(
            Operation::ForceOutput,
            format_args!(
                "slave {slave} 0x{index:04X}:{subindex:02X}{}",
                if over_owner { " over_owner" } else { "" }
            ),
        )?;
        let caller = ticket.caller().to_owned();
        let forced = self.force_entry(&caller, slave, index, subindex, value, over_owner);
        ticket.finish(forced)
    }

    fn force_entry(
        &self,
        caller: &str,
        slave: SlaveName,
        index: u16,
        subindex: u8,
        value: PdInput,
        over_owner: bool,
    ) -> Result<ForceView> {
        let entry = self.pd_entry(slave, index, subindex)?;
        let bits = match (value, entry.data_type, entry.bit_length) {
            (PdInput::Real(v), 0x0008, 32) => i64::from((v as f32).to_bits()),
            (PdInput::Real(v), 0x0011, 64) => v.to_bits() as i64,
            (PdInput::Real(v), _, _) if v.fract() == 0.0 && v.abs() < 9.0e15 => v as i64,
            (PdInput::Real(v), _, _) => {
                return Err(ApiError::invalid_field(
                    "value",
                    format!(
                        "{v} is not a value of {} ({} bits)",
                        type_name(&entry),
                        entry.bit_length
                    ),
                ));
            }
            (PdInput::Int(v), 0x0008 | 0x0011, _) => {
                return Err(ApiError::invalid_field(
                    "value",
                    format!("{v}: give {} a floating-point number", type_name(&entry)),
                ));
            }
            (PdInput::Int(v), _, _) => v,
        };
        let app = self
            .app
            .get()
            .ok_or_else(|| ApiError::unavailable("the application interface is not running"))?;
        let force = app
            .force(entry.clone(), bits, caller, over_owner)
            .map_err(|refusal| match refusal {
                crate::app::ForceRefusal::Owned(peer) => ApiError::outputs_owned(format!(
                    "an application (pid {} uid {}) owns the outputs; force with override to write over it",
                    peer.pid, peer.uid
                )),
                crate::app::ForceRefusal::NotOutput => ApiError::invalid_field(
                    "index",
                    format!("0x{index:04X}:{subindex:02X} of slave {slave} is an input"),
                ),
                crate::app::ForceRefusal::OutOfRange => ApiError::invalid_field(
                    "value",
                    format!(
                        "{bits} does not fit 0x{index:04X}:{subindex:02X} ({}, {} bits)",
                        type_name(&entry),
                        entry.bit_length
                    ),
                ),
            })?;
        Ok(force_view(&force))
    }

    /// Releases the force of output `index:subindex` of `slave`; not found if it is not
    /// forced.
    pub fn release_output(
        &self,
        mut ticket: Ticket,
        slave: SlaveName,
        index: u16,
        subindex: u8,
    ) -> Result<()> {
        ticket.check(
            Operation::ReleaseOutput,
            format_args!("slave {slave} 0x{index:04X}:{subindex:02X}"),
        )?;
        let caller = ticket.caller().to_owned();
        let released = self.release_entry(&caller, slave, index, subindex);
        ticket.finish(released)
    }

    fn release_entry(
        &self,
        caller: &str,
        slave: SlaveName,
        index: u16,
        subindex: u8,
    ) -> Result<()> {
        let entry = self.pd_entry(slave, index, subindex)?;
        let released = self
            .app
            .get()
            .is_some_and(|app| app.release_force(&entry, caller));
        if released {
            Ok(())
        } else {
            Err(ApiError::unknown_entry(format!(
                "0x{index:04X}:{subindex:02X} of slave {slave} is not forced"
            )))
        }
    }

    /// The forced outputs.
    pub fn forced_outputs(&self) -> Vec<ForceView> {
        self.app
            .get()
            .map(|app| app.forces().iter().map(force_view).collect())
            .unwrap_or_default()
    }
}

fn type_name(entry: &Entry) -> String {
    match entry.data_type {
        0 => "an entry of no known type".into(),
        code => DataType::from(code).to_string(),
    }
}

fn force_view(force: &crate::app::Force) -> ForceView {
    let raw = force.value.to_le_bytes();
    let raw = &raw[..usize::from(force.entry.bit_length).div_ceil(8).min(8)];
    ForceView {
        entry: PdEntryView::from(&force.entry),
        value: decode(&force.entry, raw),
        by: force.by.clone(),
        over_owner: force.over_owner,
        since: force.since,
    }
}
