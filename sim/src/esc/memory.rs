//! The ESC address space as plain bytes: 4 KiB of registers followed by the process RAM.
//!
//! Nothing here knows access rules; [`super::physical`] decides who may touch what. All
//! accessors take addresses as `u32` so that `address + length` never overflows, and return
//! zeros / do nothing outside the space instead of panicking.

use std::ops::Range;

/// First address after the register area; process RAM starts here.
pub const REGISTER_END: u32 = 0x1000;

/// Lowest address a SyncManager may cover: the digital I/O registers from 0x0F00 (simple
/// terminals such as the EL2004 put their process-data SyncManager there) and the RAM.
pub const SM_AREA_START: u32 = 0x0F00;

/// Registers and RAM of one ESC.
#[derive(Debug, Clone)]
pub(crate) struct Memory {
    bytes: Vec<u8>,
}

impl Memory {
    /// A zeroed space with `ram_size` bytes of RAM after the registers.
    pub fn new(ram_size: usize) -> Self {
        Memory {
            bytes: vec![0; REGISTER_END as usize + ram_size],
        }
    }

    /// One past the last RAM address.
    pub fn end(&self) -> u32 {
        // The space is at most 64 KiB (config caps the RAM), so this always fits.
        u32::try_from(self.bytes.len()).unwrap_or(u32::MAX)
    }

    /// Zeroes everything (power-on).
    pub fn clear(&mut self) {
        self.bytes.fill(0);
    }

    fn range(&self, addr: u32, len: usize) -> Option<Range<usize>> {
        let start = usize::try_from(addr).ok()?;
        let end = start.checked_add(len)?;
        (end <= self.bytes.len()).then_some(start..end)
    }

    /// `len` bytes at `addr`, or `None` if they are not all inside the space.
    pub fn get(&self, addr: u32, len: usize) -> Option<&[u8]> {
        let r = self.range(addr, len)?;
        self.bytes.get(r)
    }

    /// Mutable `len` bytes at `addr`, or `None` if they are not all inside the space.
    pub fn get_mut(&mut self, addr: u32, len: usize) -> Option<&mut [u8]> {
        let r = self.range(addr, len)?;
        self.bytes.get_mut(r)
    }

    /// Copies as many bytes as exist at `addr` into `out` (the rest of `out` is untouched).
    pub fn read_into(&self, addr: u32, out: &mut [u8]) {
        let start = usize::try_from(addr).unwrap_or(usize::MAX);
        if let Some(src) = self.bytes.get(start..) {
            let n = src.len().min(out.len());
            out[..n].copy_from_slice(&src[..n]);
        }
    }

    /// Writes as many bytes of `data` as fit at `addr`.
    pub fn write_from(&mut self, addr: u32, data: &[u8]) {
        let start = usize::try_from(addr).unwrap_or(usize::MAX);
        if let Some(dst) = self.bytes.get_mut(start..) {
            let n = dst.len().min(data.len());
            dst[..n].copy_from_slice(&data[..n]);
        }
    }

    /// Byte at `addr` (0 outside the space).
    pub fn u8(&self, addr: u32) -> u8 {
        self.get(addr, 1).map_or(0, |b| b[0])
    }

    /// Little-endian u16 at `addr` (0 outside the space).
    pub fn u16(&self, addr: u32) -> u16 {
        self.get(addr, 2)
            .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]))
    }

    /// Little-endian u32 at `addr` (0 outside the space).
    pub fn u32(&self, addr: u32) -> u32 {
        let mut b = [0u8; 4];
        if let Some(src) = self.get(addr, 4) {
            b.copy_from_slice(src);
        }
        u32::from_le_bytes(b)
    }

    /// Little-endian u64 at `addr` (0 outside the space).
    pub fn u64(&self, addr: u32) -> u64 {
        let mut b = [0u8; 8];
        if let Some(src) = self.get(addr, 8) {
            b.copy_from_slice(src);
        }
        u64::from_le_bytes(b)
    }

    /// Sets the byte at `addr` (ignored outside the space).
    pub fn set_u8(&mut self, addr: u32, value: u8) {
        self.write_from(addr, &[value]);
    }

    /// Sets a little-endian u16 at `addr`.
    pub fn set_u16(&mut self, addr: u32, value: u16) {
        self.write_from(addr, &value.to_le_bytes());
    }

    /// Sets a little-endian u32 at `addr`.
    pub fn set_u32(&mut self, addr: u32, value: u32) {
        self.write_from(addr, &value.to_le_bytes());
    }

    /// Sets a little-endian u64 at `addr`.
    pub fn set_u64(&mut self, addr: u32, value: u64) {
        self.write_from(addr, &value.to_le_bytes());
    }
}

/// Whether `[a, a + a_len)` and `[b, b + b_len)` share at least one address.
pub fn overlaps(a: u32, a_len: usize, b: u32, b_len: usize) -> bool {
    let a_end = u64::from(a) + a_len as u64;
    let b_end = u64::from(b) + b_len as u64;
    u64::from(a) < b_end && u64::from(b) < a_end
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accessors_stay_inside_the_space() {
        let mut m = Memory::new(1024);
        assert_eq!(m.end(), 0x1400);
        m.set_u32(0x13FE, 0xAABB_CCDD); // only 2 bytes fit
        assert_eq!(m.u16(0x13FE), 0xCCDD);
        assert_eq!(m.u32(0x13FE), 0, "straddling the end reads as 0");
        assert!(m.get(0x13FF, 2).is_none());
        assert!(m.get(u32::MAX, 2).is_none());
        let mut out = [9u8; 4];
        m.read_into(0x13FE, &mut out);
        assert_eq!(out, [0xDD, 0xCC, 9, 9]);
        m.write_from(u32::MAX, &[1, 2]);
    }

    #[test]
    fn overlap_rules() {
        assert!(overlaps(0x100, 4, 0x103, 1));
        assert!(!overlaps(0x100, 4, 0x104, 1));
        assert!(
            !overlaps(0x100, 0, 0x100, 1),
            "empty range overlaps nothing"
        );
        assert!(overlaps(0xFFFF_FFFF, 1, 0xFFFF_FFFF, 1));
    }
}
