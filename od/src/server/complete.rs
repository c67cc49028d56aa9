//! Complete access (spec-notes §coe.ca): a whole ARRAY/RECORD in one transfer, from subindex 0
//! (SI0 included, padded to 16 bits) or 1, laid out by [`crate::packing`].
//!
//! Strings (VISIBLE, OCTET, UNICODE) take part at their declared bit length, as ETG.1510
//! records such as the master's 0x8nnn need: a shorter value is padded with zeros on
//! upload, and on download a VISIBLE/UNICODE_STRING loses its zero padding again. (SOES
//! refuses such objects with 0x06010004; TwinCAT-style masters and ETG.1510 clients read
//! them whole.) Only DOMAIN, which has no meaningful declared length, is refused.

use ecat_wire::coe::{AbortCode, DataType, ObjectAccess};
use ecat_wire::register::AlState;

use super::super::access::{check_read, check_write};
use super::super::dictionary::{DictEntryInfo, Dictionary, EntryWrite};
use super::super::packing::{Layout, get_bits, put_bits};

/// What complete access needs of one entry.
struct Member {
    subindex: u8,
    access: ObjectAccess,
    data_type: DataType,
}

/// Bits an entry occupies in the image: its declared length (for strings their capacity);
/// DOMAIN cannot take part.
fn image_bits(info: &DictEntryInfo<'_>) -> Result<u16, AbortCode> {
    if info.data_type == DataType::Domain || (info.is_variable_length() && info.bit_length == 0) {
        return Err(AbortCode::CompleteAccessUnsupported);
    }
    Ok(info.bit_length)
}

/// The value a string entry stores from its field in a downloaded image: text strings
/// lose the zero padding that filled the field; OCTET_STRINGs keep every byte.
fn stored_value(data_type: DataType, mut field: Vec<u8>) -> Vec<u8> {
    match data_type {
        DataType::VisibleString => {
            let len = field.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
            field.truncate(len);
        }
        DataType::UnicodeString => {
            let len = field
                .chunks_exact(2)
                .rposition(|unit| unit != [0, 0])
                .map_or(0, |i| 2 * (i + 1));
            field.truncate(len);
        }
        _ => {}
    }
    field
}

/// The object's shape: whether it has SI0, its highest subindex.
fn shape(dict: &dyn Dictionary, index: u16, subindex: u8) -> Result<(bool, u8), AbortCode> {
    // Only "from 0" and "from 1" exist (SOES answers others with 0x06010000).
    if subindex > 1 {
        return Err(AbortCode::UnsupportedAccess);
    }
    let object = dict.object(index).ok_or(AbortCode::ObjectDoesNotExist)?;
    let has_count = object.has_count();
    if !has_count && subindex != 0 {
        return Err(AbortCode::SubindexDoesNotExist);
    }
    Ok((has_count, object.max_subindex))
}

/// Lays out the entries 1..=count (gaps skipped) after SI0 when `from_zero`.
fn plan(
    dict: &dyn Dictionary,
    index: u16,
    count: u8,
    from_zero: bool,
) -> Result<(Layout, Vec<Member>), AbortCode> {
    let mut layout = Layout::new();
    let mut members = Vec::new();
    if from_zero {
        layout.push_count();
    }
    for subindex in 1..=count {
        let Ok(info) = dict.entry(index, subindex) else {
            continue;
        };
        layout.push(subindex, info.data_type, image_bits(&info)?);
        members.push(Member {
            subindex,
            access: info.access,
            data_type: info.data_type,
        });
    }
    Ok((layout, members))
}

/// A VAR through complete access is its one value (no SI0 to pad), a string at its
/// declared length: the image length and the VAR's data type.
fn var_entry(dict: &dyn Dictionary, index: u16) -> Result<(usize, DataType), AbortCode> {
    let info = dict.entry(index, 0)?;
    let bits = image_bits(&info)?;
    Ok((usize::from(bits).div_ceil(8), info.data_type))
}

/// The current SI0 value.
fn current_count(dict: &mut dyn Dictionary, index: u16, state: AlState) -> Result<u8, AbortCode> {
    let mut si0 = Vec::with_capacity(1);
    dict.read(index, 0, state, &mut si0)?;
    Ok(si0.first().copied().unwrap_or(0))
}

/// Reads the object's image: entries up to the current SI0 value; write-only entries read
/// as zero, entries readable only in another state abort with 0x08000022.
pub(super) fn read(
    dict: &mut dyn Dictionary,
    index: u16,
    subindex: u8,
    state: AlState,
    out: &mut Vec<u8>,
) -> Result<(), AbortCode> {
    let (has_count, _) = shape(dict, index, subindex)?;
    if !has_count {
        let (len, _) = var_entry(dict, index)?;
        let start = out.len();
        dict.read(index, 0, state, out)?;
        out.resize(start + len, 0);
        return Ok(());
    }
    let count = current_count(dict, index, state)?;
    let (layout, members) = plan(dict, index, count, subindex == 0)?;
    let mut image = vec![0u8; layout.byte_len()];
    let mut value = Vec::new();
    let mut slots = layout.slots().iter();
    if subindex == 0
        && let Some(slot) = slots.next()
    {
        put_bits(&mut image, slot.bit_offset, slot.bits, &[count]);
    }
    for (slot, member) in slots.zip(&members) {
        match check_read(member.access, state) {
            Ok(()) => {}
            Err(AbortCode::WriteOnly) => continue,
            Err(code) => return Err(code),
        }
        value.clear();
        dict.read(index, member.subindex, state, &mut value)?;
        put_bits(&mut image, slot.bit_offset, slot.bits, &value);
    }
    out.extend_from_slice(&image);
    Ok(())
}

/// Writes the object from its image. The entries transferred run up to the SI0 value in
/// the data (from subindex 0, SI0 writable) or the current one; the length must match
/// exactly (0x06070010, as SOES). Read-only entries are skipped; entries writable only in
/// another state abort with 0x08000022. The dictionary stores all entries as one write.
pub(super) fn write(
    dict: &mut dyn Dictionary,
    index: u16,
    subindex: u8,
    data: &[u8],
    state: AlState,
) -> Result<(), AbortCode> {
    let (has_count, max_subindex) = shape(dict, index, subindex)?;
    if !has_count {
        let (len, data_type) = var_entry(dict, index)?;
        if data.len() != len {
            return Err(AbortCode::LengthMismatch);
        }
        let value = stored_value(data_type, data.to_vec());
        return dict.write_entries(
            index,
            &[EntryWrite {
                subindex: 0,
                data: &value,
            }],
            state,
        );
    }
    let si0_access = dict.entry(index, 0)?.access;
    let takes_count = subindex == 0 && si0_access.writable();
    let count = if takes_count {
        *data.first().ok_or(AbortCode::LengthMismatch)?
    } else {
        current_count(dict, index, state)?
    };
    if count > max_subindex {
        return Err(AbortCode::ValueTooHigh);
    }
    let (layout, members) = plan(dict, index, count, subindex == 0)?;
    if data.len() != layout.byte_len() {
        return Err(AbortCode::LengthMismatch);
    }
    let mut values: Vec<(u8, Vec<u8>)> = Vec::with_capacity(members.len() + 1);
    let mut slots = layout.slots().iter();
    if subindex == 0 {
        slots.next();
        if takes_count {
            check_write(si0_access, state)?;
            values.push((0, vec![count]));
        }
    }
    for (slot, member) in slots.zip(&members) {
        if !member.access.writable() {
            continue;
        }
        check_write(member.access, state)?;
        let field = get_bits(data, slot.bit_offset, slot.bits);
        values.push((member.subindex, stored_value(member.data_type, field)));
    }
    if values.is_empty() {
        return Err(AbortCode::ReadOnly);
    }
    let writes: Vec<EntryWrite<'_>> = values
        .iter()
        .map(|(subindex, data)| EntryWrite {
            subindex: *subindex,
            data,
        })
        .collect();
    dict.write_entries(index, &writes, state)
}

/// The longest image a complete-access download to this object can have (all declared
/// entries), to bound a segmented download before it starts.
pub(super) fn max_len(dict: &dyn Dictionary, index: u16, subindex: u8) -> Result<usize, AbortCode> {
    let (has_count, max_subindex) = shape(dict, index, subindex)?;
    if !has_count {
        return var_entry(dict, index).map(|(len, _)| len);
    }
    Ok(plan(dict, index, max_subindex, subindex == 0)?.0.byte_len())
}
