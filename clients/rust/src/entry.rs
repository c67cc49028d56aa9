//! One mapped entry of the process image as the entry table of the image region gives it
//! (docs/application.md, "An entry"), and reading and writing its bits in an image.

/// Which way an entry's data goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Slave to master.
    In,
    /// Master to slave.
    Out,
}

impl Direction {
    /// `"in"` or `"out"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::In => "in",
            Direction::Out => "out",
        }
    }
}

/// Bytes of the name field.
pub const NAME_LEN: usize = 46;

/// One mapped object of one slave, with its place in the image.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Entry {
    /// Ring position of the slave.
    pub position: u16,
    /// Its station address.
    pub station: u16,
    /// The PDO that maps the entry.
    pub pdo: u16,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Input or output.
    pub direction: Direction,
    /// CoE data type code (ETG.1000.6 Table 64); 0 when not known.
    pub data_type: u16,
    /// First bit in the image (bit 0 = least significant bit of byte 0).
    pub bit_offset: u32,
    /// Bits it takes (1 to 64 for values this library reads as integers).
    pub bit_length: u16,
    /// Its name (SII or CoE), at most [`NAME_LEN`] bytes.
    pub name: String,
}

impl Entry {
    /// The 64-byte record of the entry table.
    pub fn encode(&self) -> [u8; crate::shm::ENTRY_SIZE] {
        let mut r = [0u8; crate::shm::ENTRY_SIZE];
        r[0..2].copy_from_slice(&self.position.to_le_bytes());
        r[2..4].copy_from_slice(&self.station.to_le_bytes());
        r[4..6].copy_from_slice(&self.pdo.to_le_bytes());
        r[6..8].copy_from_slice(&self.index.to_le_bytes());
        r[8] = self.subindex;
        r[9] = u8::from(self.direction == Direction::Out);
        r[10..12].copy_from_slice(&self.data_type.to_le_bytes());
        r[12..16].copy_from_slice(&self.bit_offset.to_le_bytes());
        r[16..18].copy_from_slice(&self.bit_length.to_le_bytes());
        // Cut at a character boundary so the field stays valid UTF-8.
        let mut end = self.name.len().min(NAME_LEN);
        while !self.name.is_char_boundary(end) {
            end -= 1;
        }
        r[18..18 + end].copy_from_slice(&self.name.as_bytes()[..end]);
        r
    }

    /// The entry a 64-byte record holds; `None` for a record that is not one (a direction
    /// other than 0 or 1).
    pub fn decode(r: &[u8; crate::shm::ENTRY_SIZE]) -> Option<Entry> {
        let u16_at = |at: usize| u16::from_le_bytes([r[at], r[at + 1]]);
        let direction = match r[9] {
            0 => Direction::In,
            1 => Direction::Out,
            _ => return None,
        };
        let name = &r[18..18 + NAME_LEN];
        let name = &name[..name.iter().position(|&b| b == 0).unwrap_or(NAME_LEN)];
        // ecatd writes whole characters only; of anything else, the valid beginning (a
        // replacement character would not fit the field again).
        let name = match std::str::from_utf8(name) {
            Ok(name) => name,
            Err(err) => std::str::from_utf8(&name[..err.valid_up_to()]).unwrap_or_default(),
        };
        Some(Entry {
            position: u16_at(0),
            station: u16_at(2),
            pdo: u16_at(4),
            index: u16_at(6),
            subindex: r[8],
            direction,
            data_type: u16_at(10),
            bit_offset: u32::from_le_bytes([r[12], r[13], r[14], r[15]]),
            bit_length: u16_at(16),
            name: name.to_owned(),
        })
    }

    /// Whether the CoE type is a signed integer (INTEGER8 .. INTEGER64).
    pub fn is_signed(&self) -> bool {
        matches!(self.data_type, 0x0002..=0x0004 | 0x0010 | 0x0012..=0x0015)
    }

    /// Whether its bits lie inside an image of `image_len` bytes.
    pub fn lies_in(&self, image_len: usize) -> bool {
        let end = u64::from(self.bit_offset) + u64::from(self.bit_length);
        end <= 8 * image_len as u64
    }

    /// Whether it lies inside an image of `image_len` bytes and is at most 64 bits (a value
    /// this library reads and writes as an integer).
    pub fn fits(&self, image_len: usize) -> bool {
        self.bit_length <= 64 && self.lies_in(image_len)
    }

    /// Its value in `image` as raw bits (little-endian, zero-extended); 0 if it does not fit.
    pub fn get(&self, image: &[u8]) -> u64 {
        if !self.fits(image.len()) {
            return 0;
        }
        let mut value = 0u64;
        for i in 0..u32::from(self.bit_length) {
            let bit = self.bit_offset + i;
            if image[(bit / 8) as usize] & (1 << (bit % 8)) != 0 {
                value |= 1 << i;
            }
        }
        value
    }

    /// Its value in `image` as an integer: sign-extended for the signed CoE types.
    pub fn get_i64(&self, image: &[u8]) -> i64 {
        let raw = self.get(image);
        let bits = u32::from(self.bit_length);
        if self.is_signed() && (1..64).contains(&bits) && raw & (1 << (bits - 1)) != 0 {
            (raw | (u64::MAX << bits)) as i64
        } else {
            raw as i64
        }
    }

    /// Writes the low `bit_length` bits of `value` into `image`; false if it does not fit.
    pub fn set(&self, image: &mut [u8], value: u64) -> bool {
        if !self.fits(image.len()) {
            return false;
        }
        for i in 0..u32::from(self.bit_length) {
            let bit = self.bit_offset + i;
            let byte = &mut image[(bit / 8) as usize];
            if value & (1 << i) != 0 {
                *byte |= 1 << (bit % 8);
            } else {
                *byte &= !(1 << (bit % 8));
            }
        }
        true
    }

    /// Whether `value` is representable in the entry's bits (as its type is signed or not).
    pub fn accepts(&self, value: i64) -> bool {
        let bits = u32::from(self.bit_length);
        if bits == 0 {
            return value == 0;
        }
        if bits >= 64 {
            return true;
        }
        if self.is_signed() {
            let min = -(1i64 << (bits - 1));
            let max = (1i64 << (bits - 1)) - 1;
            (min..=max).contains(&value)
        } else {
            (0..(1i64 << bits)).contains(&value)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(bit_offset: u32, bit_length: u16, data_type: u16) -> Entry {
        Entry {
            position: 3,
            station: 1004,
            pdo: 0x1A00,
            index: 0x6064,
            subindex: 0,
            direction: Direction::In,
            data_type,
            bit_offset,
            bit_length,
            name: "Position actual value".into(),
        }
    }

    #[test]
    fn a_name_that_is_not_utf8_reads_as_its_valid_beginning_and_round_trips() {
        let mut record = Entry {
            position: 1,
            station: 1002,
            pdo: 0x1a00,
            index: 0x6000,
            subindex: 1,
            direction: Direction::In,
            data_type: 1,
            bit_offset: 0,
            bit_length: 1,
            name: "Input".into(),
        }
        .encode();
        record[18 + 5..18 + 9].copy_from_slice(&[0xbf, 0xbe, b'A', b'B']);
        let entry = Entry::decode(&record).unwrap();
        assert_eq!(entry.name, "Input");
        assert_eq!(Entry::decode(&entry.encode()), Some(entry));
    }

    #[test]
    fn a_record_round_trips_and_a_long_name_is_cut_on_a_character() {
        let e = entry(37, 32, 0x0004);
        assert_eq!(Entry::decode(&e.encode()), Some(e.clone()));
        let long = Entry {
            name: "é".repeat(30),
            ..e
        };
        let back = Entry::decode(&long.encode()).unwrap();
        assert_eq!(back.name, "é".repeat(23));
        let mut bad = long.encode();
        bad[9] = 2;
        assert_eq!(Entry::decode(&bad), None);
    }

    #[test]
    fn bits_at_any_offset_read_back_signed_and_unsigned() {
        let mut image = [0u8; 8];
        let e = entry(3, 16, 0x0003);
        assert!(e.set(&mut image, (-2i64) as u64));
        assert_eq!(e.get(&image), 0xFFFE);
        assert_eq!(e.get_i64(&image), -2);
        assert_eq!(image[0] & 0b111, 0, "bits below the entry untouched");
        let unsigned = entry(3, 16, 0x0006);
        assert_eq!(unsigned.get_i64(&image), 0xFFFE);
        let bit = entry(63, 1, 0x0001);
        assert!(bit.set(&mut image, 1));
        assert_eq!(image[7], 0x80);
        assert!(!entry(60, 8, 0x0005).set(&mut image, 1));
        assert_eq!(entry(60, 8, 0x0005).get(&image), 0);
    }

    #[test]
    fn values_outside_the_type_are_not_accepted() {
        assert!(entry(0, 16, 0x0003).accepts(-32768));
        assert!(!entry(0, 16, 0x0003).accepts(32768));
        assert!(entry(0, 8, 0x0005).accepts(255));
        assert!(!entry(0, 8, 0x0005).accepts(-1));
        assert!(entry(0, 1, 0x0001).accepts(1));
        assert!(!entry(0, 1, 0x0001).accepts(2));
    }
}
