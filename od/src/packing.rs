//! The byte image of a complete-access transfer (spec-notes §coe.ca): entries concatenated in
//! subindex order; byte-sized entries start on a byte boundary, bit-sized ones (BOOLEAN,
//! BITn, any length that is not whole bytes) are packed LSB first at the current bit
//! position; SI0 of an ARRAY/RECORD takes 16 bits (its u8 and a padding byte).

use ecat_wire::coe::DataType;

use super::value::{TypeKind, bytes_for_bits};

/// Where one entry sits in the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    /// Subindex.
    pub subindex: u8,
    /// First bit of the entry in the image.
    pub bit_offset: usize,
    /// Bits the entry occupies.
    pub bits: usize,
}

impl Slot {
    /// Bytes of the entry's value (⌈bits / 8⌉).
    pub fn value_len(&self) -> usize {
        self.bits.div_ceil(8)
    }
}

/// Whether an entry is packed at bit granularity rather than byte-aligned.
pub fn is_bit_packed(data_type: DataType, bit_length: u16) -> bool {
    matches!(TypeKind::of(data_type), TypeKind::Boolean)
        || (u16::from(DataType::Bit1)..=u16::from(DataType::Bit16)).contains(&u16::from(data_type))
        || !bit_length.is_multiple_of(8)
}

/// Builds the layout of an image incrementally.
#[derive(Debug, Default)]
pub struct Layout {
    slots: Vec<Slot>,
    end: usize,
}

impl Layout {
    /// An empty layout.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds SI0 of an ARRAY/RECORD: 8 bits of value in a 16-bit, byte-aligned field.
    pub fn push_count(&mut self) {
        self.align();
        self.slots.push(Slot {
            subindex: 0,
            bit_offset: self.end,
            bits: 8,
        });
        self.end += 16;
    }

    /// Adds an entry.
    pub fn push(&mut self, subindex: u8, data_type: DataType, bit_length: u16) {
        if !is_bit_packed(data_type, bit_length) {
            self.align();
        }
        self.slots.push(Slot {
            subindex,
            bit_offset: self.end,
            bits: usize::from(bit_length),
        });
        self.end += usize::from(bit_length);
    }

    fn align(&mut self) {
        self.end = self.end.div_ceil(8) * 8;
    }

    /// The slots, in order.
    pub fn slots(&self) -> &[Slot] {
        &self.slots
    }

    /// Bytes of the whole image.
    pub fn byte_len(&self) -> usize {
        self.end.div_ceil(8)
    }
}

/// Copies `bits` bits of `value` (LSB first; missing bytes read as 0) into `image` at
/// `bit_offset`. The caller sized `image` from the layout.
pub fn put_bits(image: &mut [u8], bit_offset: usize, bits: usize, value: &[u8]) {
    if bit_offset.is_multiple_of(8) && bits.is_multiple_of(8) {
        let start = bit_offset / 8;
        let n = bits / 8;
        let copied = n.min(value.len());
        if let Some(dst) = image.get_mut(start..start + n) {
            dst[..copied].copy_from_slice(&value[..copied]);
            dst[copied..].fill(0);
        }
        return;
    }
    for i in 0..bits {
        let bit = value.get(i / 8).is_some_and(|b| b >> (i % 8) & 1 == 1);
        let at = bit_offset + i;
        if let Some(byte) = image.get_mut(at / 8) {
            let mask = 1u8 << (at % 8);
            if bit {
                *byte |= mask;
            } else {
                *byte &= !mask;
            }
        }
    }
}

/// Reads `bits` bits at `bit_offset` of `image` into ⌈bits / 8⌉ bytes, LSB first.
pub fn get_bits(image: &[u8], bit_offset: usize, bits: usize) -> Vec<u8> {
    let mut out = vec![0u8; bytes_for_bits(u16::try_from(bits).unwrap_or(u16::MAX))];
    if bit_offset.is_multiple_of(8) && bits.is_multiple_of(8) {
        let start = bit_offset / 8;
        if let Some(src) = image.get(start..start + out.len()) {
            out.copy_from_slice(src);
        }
        return out;
    }
    for i in 0..bits {
        let at = bit_offset + i;
        if image.get(at / 8).is_some_and(|b| b >> (at % 8) & 1 == 1) {
            out[i / 8] |= 1 << (i % 8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn count_is_padded_and_bits_are_packed() {
        // SI0, then BOOL, BIT2, then u16 (aligned), then BOOL.
        let mut l = Layout::new();
        l.push_count();
        l.push(1, DataType::Boolean, 1);
        l.push(2, DataType::Bit2, 2);
        l.push(3, DataType::Unsigned16, 16);
        l.push(4, DataType::Boolean, 1);
        let offsets: Vec<usize> = l.slots().iter().map(|s| s.bit_offset).collect();
        assert_eq!(offsets, [0, 16, 17, 24, 40]);
        assert_eq!(l.byte_len(), 6);
        let mut image = vec![0u8; l.byte_len()];
        put_bits(&mut image, 0, 8, &[4]);
        put_bits(&mut image, 16, 1, &[1]);
        put_bits(&mut image, 17, 2, &[3]);
        put_bits(&mut image, 24, 16, &[0x34, 0x12]);
        put_bits(&mut image, 40, 1, &[1]);
        assert_eq!(image, [4, 0, 0b111, 0x34, 0x12, 1]);
        assert_eq!(get_bits(&image, 17, 2), [3]);
        assert_eq!(get_bits(&image, 24, 16), [0x34, 0x12]);
    }
}
