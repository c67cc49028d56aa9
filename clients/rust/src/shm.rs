//! The shared memory of the application interface, byte by byte (docs/application.md): the
//! image region ecatd publishes every cycle into, read-only for programs, and the commit
//! region of one claim, written by the owner alone.
//!
//! Both sides go through [`Mapping`]: every access to a field another process may write at
//! the same time is an atomic load or store, so neither side has a data race in Rust's
//! sense, and the slot protocol ([`read_slot`], [`write_slot`]) is a seqlock over three
//! slots: the writer never waits, a reader retries.

use std::sync::atomic::{AtomicU8, AtomicU32, AtomicU64, Ordering, fence};

/// First bytes of the image region.
pub const IMAGE_MAGIC: [u8; 8] = *b"ECATAPP\0";
/// First bytes of a commit region.
pub const COMMIT_MAGIC: [u8; 8] = *b"ECATOUT\0";
/// The layout version both regions follow.
pub const VERSION: u32 = 1;
/// Slots in each ring (a reader more than two cycles slow retries).
pub const SLOTS: u32 = 3;
/// Bytes of a slot's own header (stamp and counters) before its data.
pub const SLOT_HEADER: usize = 64;
/// Bytes of one entry in the entry table.
pub const ENTRY_SIZE: usize = 64;
/// Where the entry table starts in the image region.
pub const ENTRIES_OFFSET: usize = 0x100;

/// Image region flag: ecatd publishes cycles into this region.
pub const FLAG_LIVE: u32 = 1 << 0;
/// Image region flag: a newer layout generation replaced this region; attach again.
pub const FLAG_STALE: u32 = 1 << 1;

/// Fields of the image region's header (offsets).
pub mod image {
    /// `[u8; 8]` [`IMAGE_MAGIC`](super::IMAGE_MAGIC).
    pub const MAGIC: usize = 0x000;
    /// u32 layout version.
    pub const VERSION: usize = 0x008;
    /// u32 flags ([`FLAG_LIVE`](super::FLAG_LIVE), [`FLAG_STALE`](super::FLAG_STALE)).
    pub const FLAGS: usize = 0x00C;
    /// u32 layout generation.
    pub const GENERATION: usize = 0x010;
    /// u32 bytes of the process image.
    pub const IMAGE_LEN: usize = 0x014;
    /// u32 number of entries.
    pub const ENTRY_COUNT: usize = 0x018;
    /// u32 bytes per entry.
    pub const ENTRY_SIZE: usize = 0x01C;
    /// u32 offset of the entry table.
    pub const ENTRIES: usize = 0x020;
    /// u32 offset of the first input slot.
    pub const SLOTS: usize = 0x024;
    /// u32 bytes per input slot.
    pub const SLOT_STRIDE: usize = 0x028;
    /// u32 number of input slots.
    pub const SLOT_COUNT: usize = 0x02C;
    /// u64 cycle period in nanoseconds.
    pub const PERIOD_NS: usize = 0x030;
    /// u64 the last cycle published.
    pub const CYCLE: usize = 0x038;
    /// u64 the owner's commit number the last frame carried.
    pub const APPLIED: usize = 0x040;
    /// u32 the owner's pid (0: none).
    pub const OWNER_PID: usize = 0x048;
    /// u32 the owner's uid.
    pub const OWNER_UID: usize = 0x04C;
    /// u32 the watchdog in cycles.
    pub const WATCHDOG: usize = 0x050;
    /// u32 watchdog trips since ecatd started.
    pub const TRIPS: usize = 0x054;
}

/// Fields of an input slot's header (offsets within the slot).
pub mod slot {
    /// u64 when ecatd published the cycle the slot holds: `CLOCK_MONOTONIC` in
    /// nanoseconds, taken by the bus thread as it starts writing the slot (0: an ecatd
    /// that does not write it; the field was reserved before).
    pub const PUBLISHED_NS: usize = 16;
}

/// Fields of a commit region's header (offsets).
pub mod commit {
    /// `[u8; 8]` [`COMMIT_MAGIC`](super::COMMIT_MAGIC).
    pub const MAGIC: usize = 0x000;
    /// u32 the layout generation the commits are for.
    pub const GENERATION: usize = 0x008;
    /// u32 bytes of the process image.
    pub const IMAGE_LEN: usize = 0x00C;
    /// u32 offset of the first output slot.
    pub const SLOTS: usize = 0x010;
    /// u32 bytes per output slot.
    pub const SLOT_STRIDE: usize = 0x014;
    /// u32 number of output slots.
    pub const SLOT_COUNT: usize = 0x018;
    /// u64 the owner's last commit number.
    pub const COMMIT: usize = 0x020;
    /// Where the first slot starts.
    pub const FIRST_SLOT: usize = 0x040;
}

/// `n` rounded up to a multiple of 64.
pub const fn round64(n: usize) -> usize {
    n.div_ceil(64) * 64
}

/// The shape of an image region for an image of `image_len` bytes and `entries` entries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageShape {
    /// Bytes of the process image.
    pub image_len: usize,
    /// Number of entries.
    pub entries: usize,
}

impl ImageShape {
    /// Offset of the first input slot.
    pub const fn slots(&self) -> usize {
        round64(ENTRIES_OFFSET + self.entries * ENTRY_SIZE)
    }

    /// Bytes per input slot: header, inputs, outputs as sent.
    pub const fn stride(&self) -> usize {
        SLOT_HEADER + 2 * round64(self.image_len)
    }

    /// Offset of the inputs within a slot.
    pub const fn inputs_at(&self) -> usize {
        SLOT_HEADER
    }

    /// Offset of the outputs as sent within a slot.
    pub const fn outputs_at(&self) -> usize {
        SLOT_HEADER + round64(self.image_len)
    }

    /// Bytes of the whole region (a whole number of pages).
    pub const fn len(&self) -> usize {
        (self.slots() + SLOTS as usize * self.stride()).div_ceil(4096) * 4096
    }

    /// Whether the region would be empty (it never is: the header takes a page).
    pub const fn is_empty(&self) -> bool {
        false
    }
}

/// The shape of a commit region for an image of `image_len` bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommitShape {
    /// Bytes of the process image.
    pub image_len: usize,
}

impl CommitShape {
    /// Bytes per output slot.
    pub const fn stride(&self) -> usize {
        SLOT_HEADER + round64(self.image_len)
    }

    /// Bytes of the whole region (a whole number of pages).
    pub const fn len(&self) -> usize {
        (commit::FIRST_SLOT + SLOTS as usize * self.stride()).div_ceil(4096) * 4096
    }

    /// Whether the region would be empty (it never is).
    pub const fn is_empty(&self) -> bool {
        false
    }
}

/// Shared memory mapped into this process (`mmap` of a memfd), unmapped on drop.
///
/// Every field access is atomic and bounds-checked: the other process may write any byte at
/// any time, and a region whose header lies (sizes beyond the mapping) yields errors, never
/// an access outside it.
#[derive(Debug)]
pub struct Mapping {
    ptr: *mut u8,
    len: usize,
    writable: bool,
}

// SAFETY: the mapping is plain shared memory; every access through it is atomic.
unsafe impl Send for Mapping {}
// SAFETY: as above: concurrent access from several threads is what atomics are for.
unsafe impl Sync for Mapping {}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: `ptr`/`len` are exactly what mmap returned; nothing borrows the mapping
        // past its owner's life (all accessors copy values out).
        unsafe {
            libc::munmap(self.ptr.cast(), self.len);
        }
    }
}

impl Mapping {
    /// Maps `len` bytes of `fd` shared, read-only or read-write.
    pub fn map(
        fd: std::os::fd::BorrowedFd<'_>,
        len: usize,
        writable: bool,
    ) -> std::io::Result<Mapping> {
        use std::os::fd::AsRawFd;
        if len == 0 || !len.is_multiple_of(4096) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("region of {len} bytes: not a whole number of pages"),
            ));
        }
        let prot = if writable {
            libc::PROT_READ | libc::PROT_WRITE
        } else {
            libc::PROT_READ
        };
        // SAFETY: a fresh mapping at an address the kernel picks; the fd is valid for the
        // call (borrowed).
        let ptr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                prot,
                libc::MAP_SHARED,
                fd.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(std::io::Error::last_os_error());
        }
        Ok(Mapping {
            ptr: ptr.cast(),
            len,
            writable,
        })
    }

    /// Bytes mapped.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is mapped (never: `map` refuses an empty region).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn check(&self, offset: usize, len: usize, align: usize) -> Option<()> {
        let end = offset.checked_add(len)?;
        (end <= self.len && offset.is_multiple_of(align)).then_some(())
    }

    fn u32_at(&self, offset: usize) -> Option<&AtomicU32> {
        self.check(offset, 4, 4)?;
        // SAFETY: in bounds and aligned (checked); the memory lives as long as `self`;
        // AtomicU32 has u32's layout, and all access to shared memory is atomic.
        Some(unsafe { AtomicU32::from_ptr(self.ptr.add(offset).cast()) })
    }

    fn u64_at(&self, offset: usize) -> Option<&AtomicU64> {
        self.check(offset, 8, 8)?;
        // SAFETY: as in `u32_at`.
        Some(unsafe { AtomicU64::from_ptr(self.ptr.add(offset).cast()) })
    }

    fn u8_at(&self, offset: usize) -> Option<&AtomicU8> {
        self.check(offset, 1, 1)?;
        // SAFETY: as in `u32_at`.
        Some(unsafe { AtomicU8::from_ptr(self.ptr.add(offset)) })
    }

    /// The u32 at `offset` (acquire); 0 outside the mapping.
    pub fn load_u32(&self, offset: usize) -> u32 {
        self.u32_at(offset).map_or(0, |a| a.load(Ordering::Acquire))
    }

    /// The u64 at `offset` (acquire); 0 outside the mapping.
    pub fn load_u64(&self, offset: usize) -> u64 {
        self.u64_at(offset).map_or(0, |a| a.load(Ordering::Acquire))
    }

    /// Stores `value` at `offset` (release); ignored outside the mapping or when read-only.
    pub fn store_u32(&self, offset: usize, value: u32) {
        if self.writable
            && let Some(a) = self.u32_at(offset)
        {
            a.store(value, Ordering::Release);
        }
    }

    /// Stores `value` at `offset` (release); ignored outside the mapping or when read-only.
    pub fn store_u64(&self, offset: usize, value: u64) {
        if self.writable
            && let Some(a) = self.u64_at(offset)
        {
            a.store(value, Ordering::Release);
        }
    }

    /// Copies `out.len()` bytes from `offset` (relaxed loads); false, and nothing copied,
    /// if they are not all inside the mapping.
    pub fn read_bytes(&self, offset: usize, out: &mut [u8]) -> bool {
        if self.check(offset, out.len(), 1).is_none() {
            return false;
        }
        for (i, byte) in out.iter_mut().enumerate() {
            *byte = self
                .u8_at(offset + i)
                .map_or(0, |a| a.load(Ordering::Relaxed));
        }
        true
    }

    /// Copies `data` to `offset` (relaxed stores); false, and nothing written, if it does
    /// not fit or the mapping is read-only.
    pub fn write_bytes(&self, offset: usize, data: &[u8]) -> bool {
        if !self.writable || self.check(offset, data.len(), 1).is_none() {
            return false;
        }
        for (i, byte) in data.iter().enumerate() {
            if let Some(a) = self.u8_at(offset + i) {
                a.store(*byte, Ordering::Relaxed);
            }
        }
        true
    }
}

/// Writes the slot at `slot` (its stamp first, then its data) as the seqlock's writer: the
/// stamp is 0 while the data changes and `stamp` after; `data` is a list of (offset within
/// the slot, bytes).
pub fn write_slot(map: &Mapping, slot: usize, stamp: u64, data: &[(usize, &[u8])]) {
    map.store_u64(slot, 0);
    fence(Ordering::Release);
    for (offset, bytes) in data {
        map.write_bytes(slot + offset, bytes);
    }
    map.store_u64(slot, stamp);
}

/// Reads the slot at `slot` as the seqlock's reader: true if it held `stamp` before and
/// after `copy` ran (so what `copy` read is whole), false if it was being written or
/// holds another stamp.
pub fn read_slot(map: &Mapping, slot: usize, stamp: u64, copy: impl FnOnce(&Mapping)) -> bool {
    if stamp == 0 || map.load_u64(slot) != stamp {
        return false;
    }
    copy(map);
    fence(Ordering::Acquire);
    map.load_u64(slot) == stamp
}

/// The offset of slot `number % SLOTS` in a ring starting at `first` with `stride` bytes per
/// slot.
pub fn slot_of(first: usize, stride: usize, number: u64) -> usize {
    first + (number % u64::from(SLOTS)) as usize * stride
}

#[cfg(test)]
mod tests {
    use super::*;

    fn memfd(len: usize) -> std::os::fd::OwnedFd {
        use std::os::fd::FromRawFd;
        // SAFETY: memfd_create with a NUL-terminated name; the fd is owned from here.
        let fd = unsafe { libc::memfd_create(c"test".as_ptr(), libc::MFD_CLOEXEC) };
        assert!(fd >= 0);
        // SAFETY: fd was just created and is owned by nobody else.
        let fd = unsafe { std::os::fd::OwnedFd::from_raw_fd(fd) };
        // SAFETY: a valid fd and length.
        let truncated = unsafe { libc::ftruncate(fd.as_raw_fd(), len as libc::off_t) };
        assert_eq!(truncated, 0);
        fd
    }

    use std::os::fd::{AsFd, AsRawFd};

    #[test]
    fn shapes_put_slots_after_the_entries_on_64_byte_boundaries() {
        let shape = ImageShape {
            image_len: 14,
            entries: 21,
        };
        assert_eq!(shape.slots(), round64(0x100 + 21 * 64));
        assert_eq!(shape.stride(), 64 + 64 + 64);
        assert_eq!(shape.outputs_at(), 128);
        assert_eq!(shape.len() % 4096, 0);
        assert!(shape.len() >= shape.slots() + 3 * shape.stride());
        assert_eq!(CommitShape { image_len: 200 }.stride(), 64 + 256);
    }

    #[test]
    fn a_slot_reads_whole_only_with_its_stamp() {
        let fd = memfd(4096);
        let writer = Mapping::map(fd.as_fd(), 4096, true).unwrap();
        let reader = Mapping::map(fd.as_fd(), 4096, false).unwrap();
        write_slot(&writer, 64, 7, &[(64, &[1, 2, 3])]);
        let mut got = [0u8; 3];
        assert!(read_slot(&reader, 64, 7, |m| {
            m.read_bytes(128, &mut got);
        }));
        assert_eq!(got, [1, 2, 3]);
        // Another stamp, or the slot under way (stamp 0), is refused.
        assert!(!read_slot(&reader, 64, 8, |_| {}));
        writer.store_u64(64, 0);
        assert!(!read_slot(&reader, 64, 7, |_| {}));
        // A stamp that changes while the reader copies is caught.
        writer.store_u64(64, 7);
        assert!(!read_slot(&reader, 64, 7, |_| writer.store_u64(64, 10)));
    }

    #[test]
    fn a_read_only_mapping_writes_nothing_and_nothing_reaches_past_the_end() {
        let fd = memfd(4096);
        let reader = Mapping::map(fd.as_fd(), 4096, false).unwrap();
        reader.store_u64(0, 5);
        assert!(!reader.write_bytes(0, &[1]));
        assert_eq!(reader.load_u64(0), 0);
        assert_eq!(reader.load_u64(4096), 0);
        assert_eq!(reader.load_u32(4094), 0);
        let mut buf = [0u8; 8];
        assert!(!reader.read_bytes(4090, &mut buf));
        assert!(Mapping::map(fd.as_fd(), 100, false).is_err());
    }
}
