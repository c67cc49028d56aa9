//! A slave's SoE server from its description: the default IDN set of every drive, then the
//! IDNs the description adds or overrides.

use ecat_wire::soe::SoeAttribute;

use crate::device::soe::{IdnEntry, SoeService};

use super::model::{IdnSpec, SlaveSpec};

/// Attribute bits 23 and 31: reserved, always 0.
const RESERVED_ATTRIBUTE_BITS: u32 = 0x8080_0000;

/// The SoE service of `spec`, or why its IDNs make no sense.
pub(crate) fn soe_service(spec: &SlaveSpec) -> Result<SoeService, String> {
    let mut service = SoeService::new(spec.soe_drives);
    for idn in &spec.idns {
        let entry = idn_entry(idn).map_err(|reason| format!("IDN 0x{:04X}: {reason}", idn.idn))?;
        let drives = match idn.drive {
            Some(drive) if drive < service.drives() => drive..drive + 1,
            Some(drive) => {
                return Err(format!(
                    "IDN 0x{:04X}: drive {drive}, but the slave has {} (soe_drives)",
                    idn.idn,
                    service.drives()
                ));
            }
            None => 0..service.drives(),
        };
        for drive in drives {
            service
                .insert(drive, idn.idn, entry.clone())
                .map_err(|e| format!("IDN 0x{:04X}: {e:?}", idn.idn))?;
        }
    }
    Ok(service)
}

/// One IDN's elements, checked against its attribute.
fn idn_entry(spec: &IdnSpec) -> Result<IdnEntry, String> {
    if spec.attribute & RESERVED_ATTRIBUTE_BITS != 0 {
        return Err(format!(
            "attribute 0x{:08X} sets reserved bits 23 or 31",
            spec.attribute
        ));
    }
    let attribute = SoeAttribute::from_u32(spec.attribute);
    let value = spec
        .value
        .clone()
        .or_else(|| spec.default.clone())
        .ok_or("needs a value or a default")?;
    let size = usize::from(attribute.element_size);
    let fits = |what: &str, bytes: &[u8]| -> Result<(), String> {
        let ok = if attribute.list {
            bytes.len().is_multiple_of(size)
        } else {
            bytes.len() == size
        };
        if ok {
            Ok(())
        } else if attribute.list {
            Err(format!(
                "{what} has {} bytes, not a whole number of {size}-byte list elements",
                bytes.len()
            ))
        } else {
            Err(format!(
                "{what} has {} bytes, the attribute says {size}",
                bytes.len()
            ))
        }
    };
    fits("value", &value)?;
    for (what, bytes) in [
        ("min", &spec.min),
        ("max", &spec.max),
        ("default", &spec.default),
    ] {
        if let Some(bytes) = bytes {
            fits(what, bytes)?;
        }
    }
    let list_capacity = if attribute.list {
        let len = u16::try_from(value.len()).map_err(|_| "value longer than 65535 bytes")?;
        let capacity = spec.list_capacity.unwrap_or(len);
        if capacity < len {
            return Err(format!(
                "list_capacity {capacity} is below the value's {len} bytes"
            ));
        }
        capacity
    } else {
        0
    };
    Ok(IdnEntry {
        data_state: 0,
        name: Some(spec.name.clone()),
        attribute,
        unit: spec.unit.clone(),
        minimum: spec.min.clone(),
        maximum: spec.max.clone(),
        value,
        default: spec.default.clone(),
        read_only: spec.read_only,
        list_capacity,
    })
}
