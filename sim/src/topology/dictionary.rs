//! A slave's CoE dictionary from its description: the standard objects of the
//! communication area (spec-notes §coe.objects, §coe.pdo) derived from its identity and
//! PDOs, then the extra objects the description lists.

use std::collections::BTreeMap;

use ecat_od::access::presets::{RO_TX, RW_PREOP, RW_RX, WO};
use ecat_od::{DictionaryBuilder, Entry, Object, PdoEntry, SmType, StaticDictionary};
use ecat_od::{Identity, ValueError};
use ecat_wire::coe::{DataType, ObjectAccess, ObjectCode};

use super::model::{CoeObject, SlaveSpec, pattern};

/// A data type by its CoE name (`UNSIGNED16`, ...).
pub(crate) fn data_type(name: &str) -> Option<DataType> {
    (0u16..0x40)
        .map(DataType::from)
        .find(|dt| dt.name().eq_ignore_ascii_case(name))
}

fn access(name: &str) -> Option<ObjectAccess> {
    Some(match name {
        "ro" => ObjectAccess::RO,
        "rw" => ObjectAccess::RW,
        "wo" => WO,
        "rw_preop" => RW_PREOP,
        "ro_tx" => RO_TX,
        "rw_rx" => RW_RX,
        _ => return None,
    })
}

fn value_error(index: u16, subindex: u8, e: ValueError) -> String {
    format!("0x{index:04X}:{subindex:02X}: {e}")
}

/// One entry from its description.
fn entry(obj: &CoeObject) -> Result<Entry, String> {
    let at = format!("0x{:04X}:{:02X}", obj.index, obj.subindex);
    let dt = data_type(&obj.data_type)
        .ok_or_else(|| format!("{at}: unknown data type {:?}", obj.data_type))?;
    let access =
        access(&obj.access).ok_or_else(|| format!("{at}: unknown access {:?}", obj.access))?;
    typed_entry(obj, dt, access).map_err(|e| value_error(obj.index, obj.subindex, e))
}

fn typed_entry(obj: &CoeObject, dt: DataType, access: ObjectAccess) -> Result<Entry, ValueError> {
    let v = obj.value.as_ref();
    let int = || v.and_then(toml::Value::as_integer).unwrap_or(0);
    let sub = obj.subindex;
    let name = obj.name.as_str();
    let bytes_entry = |bytes: Vec<u8>| {
        let len = bytes.len().max(obj.size.unwrap_or(0));
        Ok(Entry::with_capacity(sub, name, dt, access, bytes, len))
    };
    let conv = |_| ValueError::OutOfRange {
        data_type: dt,
        value: int().to_string(),
    };
    match dt {
        DataType::Boolean => {
            let b = v.and_then(toml::Value::as_bool).unwrap_or(int() != 0);
            Entry::new(sub, name, dt, access, b)
        }
        DataType::Integer8 => Entry::new(sub, name, dt, access, i8::try_from(int()).map_err(conv)?),
        DataType::Integer16 => {
            Entry::new(sub, name, dt, access, i16::try_from(int()).map_err(conv)?)
        }
        DataType::Integer32 => {
            Entry::new(sub, name, dt, access, i32::try_from(int()).map_err(conv)?)
        }
        DataType::Integer64 => Entry::new(sub, name, dt, access, int()),
        DataType::Unsigned8 => {
            Entry::new(sub, name, dt, access, u8::try_from(int()).map_err(conv)?)
        }
        DataType::Unsigned16 => {
            Entry::new(sub, name, dt, access, u16::try_from(int()).map_err(conv)?)
        }
        DataType::Unsigned32 => {
            Entry::new(sub, name, dt, access, u32::try_from(int()).map_err(conv)?)
        }
        DataType::Unsigned64 => {
            Entry::new(sub, name, dt, access, u64::try_from(int()).map_err(conv)?)
        }
        DataType::Real32 => {
            let f = v.and_then(toml::Value::as_float).unwrap_or(0.0);
            Entry::new(sub, name, dt, access, f as f32)
        }
        DataType::Real64 => {
            let f = v.and_then(toml::Value::as_float).unwrap_or(0.0);
            Entry::new(sub, name, dt, access, f)
        }
        DataType::VisibleString => bytes_entry(
            v.and_then(toml::Value::as_str)
                .unwrap_or("")
                .as_bytes()
                .to_vec(),
        ),
        DataType::OctetString | DataType::Domain | DataType::UnicodeString => {
            if let Some(list) = v.and_then(toml::Value::as_array) {
                // Binary contents as a list of byte values.
                let data = list
                    .iter()
                    .map(|b| {
                        b.as_integer()
                            .and_then(|b| u8::try_from(b).ok())
                            .ok_or_else(|| ValueError::OutOfRange {
                                data_type: dt,
                                value: b.to_string(),
                            })
                    })
                    .collect::<Result<Vec<u8>, _>>()?;
                return bytes_entry(data);
            }
            match v.and_then(toml::Value::as_str) {
                Some(text) => bytes_entry(text.as_bytes().to_vec()),
                None => bytes_entry(pattern(obj.size.unwrap_or(0))),
            }
        }
        _ => Err(ValueError::TypeMismatch {
            data_type: dt,
            rust_type: "a topology value",
        }),
    }
}

/// Adds the described extra objects: VARs for subindex 0, RECORDs for the rest.
fn extra_objects(
    mut b: DictionaryBuilder,
    objects: &[CoeObject],
) -> Result<DictionaryBuilder, String> {
    let mut records: BTreeMap<u16, Vec<&CoeObject>> = BTreeMap::new();
    for obj in objects {
        if obj.subindex == 0 {
            let e = entry(obj)?;
            b = b.object(Object {
                index: obj.index,
                name: obj.name.clone(),
                object_code: ObjectCode::Var,
                data_type: e.data_type,
                entries: vec![e],
                zero_count_to_write: false,
            });
        } else {
            records.entry(obj.index).or_default().push(obj);
        }
    }
    for (index, entries) in records {
        let mut built = Vec::new();
        for obj in entries {
            built.push(entry(obj)?);
        }
        b = b.record(index, &format!("Object 0x{index:04X}"), |mut r| {
            for e in built {
                r = r.raw(e);
            }
            r
        });
    }
    Ok(b)
}

/// The CoE dictionary: standard objects derived from the description, then the extras.
pub(crate) fn dictionary(spec: &SlaveSpec) -> Result<StaticDictionary, String> {
    let mut b = StaticDictionary::builder()
        .device_type(spec.device_type)
        .error_register(0)
        .device_name(&spec.name)
        .identity(Identity {
            vendor_id: spec.vendor_id,
            product_code: spec.product_code,
            revision: spec.revision,
            serial: spec.serial,
        });
    let mut sm_types = vec![SmType::MailboxOut, SmType::MailboxIn];
    let max_sm = spec.pdos.iter().map(|p| p.sm).max().unwrap_or(3).max(3);
    for sm in 2..=max_sm {
        let pdo = spec.pdos.iter().find(|p| p.sm == sm);
        sm_types.push(match pdo {
            Some(p) if p.is_rx() => SmType::Outputs,
            Some(_) => SmType::Inputs,
            None if sm == 2 => SmType::Outputs,
            None if sm == 3 => SmType::Inputs,
            None => SmType::Unused,
        });
    }
    b = b.sm_types(&sm_types);
    for pdo in &spec.pdos {
        let entries: Vec<PdoEntry> = pdo
            .entries
            .iter()
            .map(|e| PdoEntry::new(e.index, e.subindex, e.bits))
            .collect();
        b = b.pdo_mapping(pdo.index, &pdo.name, &entries, 8);
    }
    let assigned = |rx: bool| -> Vec<u16> {
        spec.pdos
            .iter()
            .filter(|p| p.is_rx() == rx)
            .map(|p| p.index)
            .collect()
    };
    b = b
        .rx_pdo_assign(&assigned(true), 4)
        .tx_pdo_assign(&assigned(false), 4);
    extra_objects(b, &spec.objects)?
        .build()
        .map_err(|e| e.to_string())
}
