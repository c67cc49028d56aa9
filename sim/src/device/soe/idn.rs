//! One IDN of a simulated drive: its elements, how they are encoded for a read, and the
//! checks a value write goes through (ETG.1000.6, spec-notes §soe).

use ecat_wire::register::al::AlState;
use ecat_wire::soe::{ElementFlags, SoeAttribute, SoeDataType, SoeError};

/// The elements of one IDN.
///
/// `value`, `minimum`, `maximum` and `default` hold the element data as it travels: the
/// little-endian number for fixed-size IDNs, or the list *contents* (without the 4-byte
/// current/maximum length header, which is added on read) for list IDNs.
#[derive(Debug, Clone, PartialEq)]
pub struct IdnEntry {
    /// Element 1, data state (u16).
    pub data_state: u16,
    /// Element 2, name; `None` answers a read with 0x2001.
    pub name: Option<String>,
    /// Element 3, attribute: size, list, data type, write protection.
    pub attribute: SoeAttribute,
    /// Element 4, unit; `None` answers a read with 0x4001.
    pub unit: Option<String>,
    /// Element 5, minimum input value; `None` answers a read with 0x5001.
    pub minimum: Option<Vec<u8>>,
    /// Element 6, maximum input value; `None` answers a read with 0x6001.
    pub maximum: Option<Vec<u8>>,
    /// Element 7, operation data.
    pub value: Vec<u8>,
    /// Default value; `None` answers a read with 0x8001.
    pub default: Option<Vec<u8>>,
    /// The value cannot be written at all (0x7004).
    pub read_only: bool,
    /// For list IDNs: the maximum length in bytes (the "max length" of the list header).
    pub list_capacity: u16,
}

const fn attribute(element_size: u8, list: bool, data_type: SoeDataType) -> SoeAttribute {
    SoeAttribute {
        conversion_factor: 1,
        element_size,
        list,
        procedure_command: false,
        data_type,
        decimal_places: 0,
        write_protected_preop: false,
        write_protected_safeop: false,
        write_protected_op: false,
    }
}

impl IdnEntry {
    /// A fixed-size IDN with the given attribute and little-endian value.
    pub fn fixed(name: &str, attribute: SoeAttribute, value: Vec<u8>) -> Self {
        IdnEntry {
            data_state: 0,
            name: Some(name.to_owned()),
            attribute,
            unit: None,
            minimum: None,
            maximum: None,
            value,
            default: None,
            read_only: false,
            list_capacity: 0,
        }
    }

    /// A u16 IDN of `data_type` (unsigned, binary, hex).
    pub fn u16(name: &str, data_type: SoeDataType, value: u16) -> Self {
        Self::fixed(
            name,
            attribute(2, false, data_type),
            value.to_le_bytes().to_vec(),
        )
    }

    /// An unsigned 32-bit IDN.
    pub fn u32(name: &str, value: u32) -> Self {
        Self::fixed(
            name,
            attribute(4, false, SoeDataType::Unsigned),
            value.to_le_bytes().to_vec(),
        )
    }

    /// A signed 32-bit IDN.
    pub fn i32(name: &str, value: i32) -> Self {
        Self::fixed(
            name,
            attribute(4, false, SoeDataType::Signed),
            value.to_le_bytes().to_vec(),
        )
    }

    /// A text IDN (list of 1-byte characters) holding `text`, with room for `capacity` bytes.
    pub fn text(name: &str, text: &str, capacity: u16) -> Self {
        IdnEntry {
            list_capacity: capacity.max(clamp_len(text.len())),
            ..Self::fixed(
                name,
                attribute(1, true, SoeDataType::String),
                text.as_bytes().to_vec(),
            )
        }
    }

    /// An IDN list (list of u16 IDNs), with room for `capacity` IDNs.
    pub fn idn_list(name: &str, idns: &[u16], capacity: u16) -> Self {
        let value: Vec<u8> = idns.iter().flat_map(|i| i.to_le_bytes()).collect();
        IdnEntry {
            list_capacity: capacity.saturating_mul(2).max(clamp_len(value.len())),
            ..Self::fixed(name, attribute(2, true, SoeDataType::Idn), value)
        }
    }

    /// With a unit.
    pub fn with_unit(mut self, unit: &str) -> Self {
        self.unit = Some(unit.to_owned());
        self
    }

    /// With minimum and maximum input values (same encoding as the value).
    pub fn with_limits(mut self, minimum: Vec<u8>, maximum: Vec<u8>) -> Self {
        self.minimum = Some(minimum);
        self.maximum = Some(maximum);
        self
    }

    /// With a default value; the current value is reset to it.
    pub fn with_default(mut self, default: Vec<u8>) -> Self {
        self.value = default.clone();
        self.default = Some(default);
        self
    }

    /// Value not writable (0x7004).
    pub fn read_only(mut self) -> Self {
        self.read_only = true;
        self
    }

    /// Value write-protected in the given states (attribute bits 28-30; 0x7005).
    pub fn protected_in(mut self, preop: bool, safeop: bool, op: bool) -> Self {
        self.attribute.write_protected_preop = preop;
        self.attribute.write_protected_safeop = safeop;
        self.attribute.write_protected_op = op;
        self
    }

    /// The data of the elements in `elements`, concatenated in bit order (data state, name,
    /// attribute, unit, min, max, value, default), or the error for the first one missing.
    pub fn read(&self, elements: ElementFlags) -> Result<Vec<u8>, SoeError> {
        if elements.is_empty() {
            return Err(SoeError::NoElementAddressed);
        }
        let mut out = Vec::new();
        let wanted = |flag| elements.contains(flag);
        if wanted(ElementFlags::DATA_STATE) {
            out.extend_from_slice(&self.data_state.to_le_bytes());
        }
        if wanted(ElementFlags::NAME) {
            let name = self.name.as_deref().ok_or(SoeError::NoName)?;
            push_list(&mut out, name.as_bytes(), clamp_len(name.len()));
        }
        if wanted(ElementFlags::ATTRIBUTE) {
            let raw = self
                .attribute
                .to_u32()
                .map_err(|_| SoeError::GeneralError)?;
            out.extend_from_slice(&raw.to_le_bytes());
        }
        if wanted(ElementFlags::UNIT) {
            let unit = self.unit.as_deref().ok_or(SoeError::NoUnit)?;
            push_list(&mut out, unit.as_bytes(), clamp_len(unit.len()));
        }
        if wanted(ElementFlags::MINIMUM) {
            let min = self.minimum.as_deref().ok_or(SoeError::NoMinimum)?;
            self.push_data(&mut out, min);
        }
        if wanted(ElementFlags::MAXIMUM) {
            let max = self.maximum.as_deref().ok_or(SoeError::NoMaximum)?;
            self.push_data(&mut out, max);
        }
        if wanted(ElementFlags::VALUE) {
            self.push_data(&mut out, &self.value);
        }
        if wanted(ElementFlags::DEFAULT) {
            let default = self.default.as_deref().ok_or(SoeError::NoDefault)?;
            self.push_data(&mut out, default);
        }
        Ok(out)
    }

    fn push_data(&self, out: &mut Vec<u8>, data: &[u8]) {
        if self.attribute.list {
            push_list(out, data, self.list_capacity);
        } else {
            out.extend_from_slice(data);
        }
    }

    /// Writes `data` into the elements named by `elements` in AL state `state`.
    ///
    /// Only the value (operation data) is writable; asking to write any other element answers
    /// that element's "cannot be changed" code, the first in bit order.
    pub fn write(
        &mut self,
        elements: ElementFlags,
        data: &[u8],
        state: AlState,
    ) -> Result<(), SoeError> {
        if elements.is_empty() {
            return Err(SoeError::NoElementAddressed);
        }
        let read_only_elements = [
            (ElementFlags::DATA_STATE, SoeError::InvalidAccessElement1),
            (ElementFlags::NAME, SoeError::NameReadOnly),
            (ElementFlags::ATTRIBUTE, SoeError::AttributeReadOnly),
            (ElementFlags::UNIT, SoeError::UnitReadOnly),
            (ElementFlags::MINIMUM, SoeError::MinimumReadOnly),
            (ElementFlags::MAXIMUM, SoeError::MaximumReadOnly),
        ];
        for (flag, code) in read_only_elements {
            if elements.contains(flag) {
                return Err(code);
            }
        }
        if elements.contains(ElementFlags::DEFAULT) {
            return Err(SoeError::DefaultReadOnly);
        }
        if self.read_only {
            return Err(SoeError::DataReadOnly);
        }
        if self.protected_now(state) {
            return Err(SoeError::DataWriteProtected);
        }
        let value = if self.attribute.list {
            self.check_list(data)?
        } else {
            self.check_fixed(data)?
        };
        self.value = value;
        Ok(())
    }

    fn protected_now(&self, state: AlState) -> bool {
        let a = &self.attribute;
        match state {
            AlState::PreOp => a.write_protected_preop,
            AlState::SafeOp => a.write_protected_safeop,
            AlState::Op => a.write_protected_op,
            _ => false,
        }
    }

    /// A list write carries the list header: u16 current length, u16 maximum, contents.
    fn check_list(&self, data: &[u8]) -> Result<Vec<u8>, SoeError> {
        let (Some(cur), Some(contents)) = (data.get(..2), data.get(4..)) else {
            return Err(SoeError::DataTooShort);
        };
        let cur = usize::from(u16::from_le_bytes([cur[0], cur[1]]));
        if contents.len() < cur {
            return Err(SoeError::DataTooShort);
        }
        if contents.len() > cur || cur > usize::from(self.list_capacity) {
            return Err(SoeError::DataTooLong);
        }
        if cur % usize::from(self.attribute.element_size) != 0 {
            return Err(SoeError::InvalidData);
        }
        Ok(contents.to_vec())
    }

    fn check_fixed(&self, data: &[u8]) -> Result<Vec<u8>, SoeError> {
        let size = usize::from(self.attribute.element_size);
        if data.len() < size {
            return Err(SoeError::DataTooShort);
        }
        if data.len() > size {
            return Err(SoeError::DataTooLong);
        }
        let ty = self.attribute.data_type;
        let below = |min: &Vec<u8>| compare(ty, data, min) == Some(std::cmp::Ordering::Less);
        let above = |max: &Vec<u8>| compare(ty, data, max) == Some(std::cmp::Ordering::Greater);
        if self.minimum.as_ref().is_some_and(below) {
            return Err(SoeError::DataBelowMinimum);
        }
        if self.maximum.as_ref().is_some_and(above) {
            return Err(SoeError::DataAboveMaximum);
        }
        Ok(data.to_vec())
    }
}

/// Lengths in list headers are u16; longer texts are cut in the header (never in practice).
fn clamp_len(len: usize) -> u16 {
    u16::try_from(len).unwrap_or(u16::MAX)
}

/// Appends SoE list format: u16 current length, u16 maximum length, contents.
fn push_list(out: &mut Vec<u8>, contents: &[u8], max: u16) {
    let cur = clamp_len(contents.len());
    out.extend_from_slice(&cur.to_le_bytes());
    out.extend_from_slice(&max.max(cur).to_le_bytes());
    out.extend_from_slice(contents);
}

/// Compares two little-endian numbers of the same size by the IDN's data type; `None` when
/// they cannot be compared (different sizes, a size the type does not have, NaN).
fn compare(ty: SoeDataType, a: &[u8], b: &[u8]) -> Option<std::cmp::Ordering> {
    if a.len() != b.len() || a.is_empty() || a.len() > 8 {
        return None;
    }
    let widen = |bytes: &[u8], signed: bool| {
        let negative = signed && bytes.last().is_some_and(|&b| b & 0x80 != 0);
        let mut buf = if negative { [0xFF; 8] } else { [0; 8] };
        buf[..bytes.len()].copy_from_slice(bytes);
        buf
    };
    match ty {
        SoeDataType::Signed => {
            let x = i64::from_le_bytes(widen(a, true));
            let y = i64::from_le_bytes(widen(b, true));
            Some(x.cmp(&y))
        }
        SoeDataType::Float if a.len() == 4 => {
            let f = |v: &[u8]| f32::from_le_bytes([v[0], v[1], v[2], v[3]]);
            f(a).partial_cmp(&f(b))
        }
        SoeDataType::Float if a.len() == 8 => {
            let f = |v: &[u8]| f64::from_le_bytes(widen(v, false));
            f(a).partial_cmp(&f(b))
        }
        _ => {
            let x = u64::from_le_bytes(widen(a, false));
            let y = u64::from_le_bytes(widen(b, false));
            Some(x.cmp(&y))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_come_in_bit_order() {
        let entry = IdnEntry::u16("Mode", SoeDataType::Hex, 0x0102).with_unit("-");
        let data = entry
            .read(ElementFlags::VALUE | ElementFlags::NAME | ElementFlags::UNIT)
            .unwrap();
        let mut expected = vec![4, 0, 4, 0];
        expected.extend_from_slice(b"Mode");
        expected.extend_from_slice(&[1, 0, 1, 0, b'-']);
        expected.extend_from_slice(&[0x02, 0x01]);
        assert_eq!(data, expected);
    }

    #[test]
    fn signed_limits() {
        let mut entry = IdnEntry::i32("v", 0).with_limits(
            (-10i32).to_le_bytes().to_vec(),
            10i32.to_le_bytes().to_vec(),
        );
        let write = |e: &mut IdnEntry, v: i32| {
            e.write(ElementFlags::VALUE, &v.to_le_bytes(), AlState::PreOp)
        };
        assert_eq!(write(&mut entry, -11), Err(SoeError::DataBelowMinimum));
        assert_eq!(write(&mut entry, 11), Err(SoeError::DataAboveMaximum));
        assert_eq!(write(&mut entry, -10), Ok(()));
        assert_eq!(entry.value, (-10i32).to_le_bytes());
    }

    #[test]
    fn list_write_checks_the_header() {
        let mut entry = IdnEntry::idn_list("l", &[1], 2);
        let ok = [4, 0, 4, 0, 0x33, 0, 0x28, 0];
        assert_eq!(
            entry.write(ElementFlags::VALUE, &ok, AlState::PreOp),
            Ok(())
        );
        let long = [6, 0, 6, 0, 1, 0, 2, 0, 3, 0];
        assert_eq!(
            entry.write(ElementFlags::VALUE, &long, AlState::PreOp),
            Err(SoeError::DataTooLong)
        );
        assert_eq!(
            entry.write(ElementFlags::VALUE, &[4, 0, 4, 0, 1], AlState::PreOp),
            Err(SoeError::DataTooShort)
        );
        assert_eq!(entry.read(ElementFlags::VALUE).unwrap(), ok);
    }
}
