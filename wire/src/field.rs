//! Field ranges and little-endian access shared by every wire structure.
//!
//! EtherCAT is little-endian throughout (only the Ethernet header is big-endian). Accessors
//! call these with offsets from a `mod field` table; they index the slice directly, so a
//! caller must have checked the length first (`check_len` / `new_checked`).

/// A byte range inside a structure.
pub type Field = core::ops::Range<usize>;
/// The open-ended remainder of a structure, from an offset to the end.
pub type Rest = core::ops::RangeFrom<usize>;

/// Reads a little-endian u16 at `at`.
#[inline]
pub fn u16_le(buf: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([buf[at], buf[at + 1]])
}

/// Reads a little-endian u32 at `at`.
#[inline]
pub fn u32_le(buf: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([buf[at], buf[at + 1], buf[at + 2], buf[at + 3]])
}

/// Reads a little-endian u64 at `at`.
#[inline]
pub fn u64_le(buf: &[u8], at: usize) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&buf[at..at + 8]);
    u64::from_le_bytes(b)
}

/// Writes a little-endian u16 at `at`.
#[inline]
pub fn set_u16_le(buf: &mut [u8], at: usize, value: u16) {
    buf[at..at + 2].copy_from_slice(&value.to_le_bytes());
}

/// Writes a little-endian u32 at `at`.
#[inline]
pub fn set_u32_le(buf: &mut [u8], at: usize, value: u32) {
    buf[at..at + 4].copy_from_slice(&value.to_le_bytes());
}

/// Writes a little-endian u64 at `at`.
#[inline]
pub fn set_u64_le(buf: &mut [u8], at: usize, value: u64) {
    buf[at..at + 8].copy_from_slice(&value.to_le_bytes());
}
