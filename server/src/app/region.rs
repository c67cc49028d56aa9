//! The shared regions of the application interface (docs/application.md): one image region
//! per layout generation, written by the bus thread and mapped read-only by every program,
//! and one commit region per claim, written by its owner alone.

use std::os::fd::{AsFd, AsRawFd, FromRawFd, OwnedFd};

use ecat_app::entry::Entry;
use ecat_app::shm::{
    self, COMMIT_MAGIC, CommitShape, IMAGE_MAGIC, ImageShape, Mapping, commit, image,
};

/// A memfd of `len` bytes (zeroed), closed on exec.
fn memfd(name: &std::ffi::CStr, len: usize) -> std::io::Result<OwnedFd> {
    // SAFETY: a NUL-terminated name and valid flags.
    let fd = unsafe { libc::memfd_create(name.as_ptr(), libc::MFD_CLOEXEC) };
    if fd < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: the fd was just created and nobody else owns it.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    let size = libc::off_t::try_from(len)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "region too large"))?;
    // SAFETY: a valid fd and size.
    if unsafe { libc::ftruncate(fd.as_raw_fd(), size) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(fd)
}

/// `CLOCK_MONOTONIC` in nanoseconds: the clock every process on this machine shares, so a
/// program can compare a cycle's publication with its own wake-up.
fn monotonic_ns() -> u64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid clock id and a live timespec to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    let seconds = u64::try_from(now.tv_sec).unwrap_or(0);
    let nanos = u64::try_from(now.tv_nsec).unwrap_or(0);
    seconds.saturating_mul(1_000_000_000).saturating_add(nanos)
}

/// A second, read-only open file description of the memfd `fd`: a program mapping it
/// cannot write (mmap with `PROT_WRITE` and `MAP_SHARED` fails with `EACCES`).
fn read_only(fd: &OwnedFd) -> std::io::Result<OwnedFd> {
    let path = format!("/proc/self/fd/{}\0", fd.as_raw_fd());
    // SAFETY: a NUL-terminated path.
    let ro = unsafe { libc::open(path.as_ptr().cast(), libc::O_RDONLY | libc::O_CLOEXEC) };
    if ro < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: just opened, owned by nobody else.
    Ok(unsafe { OwnedFd::from_raw_fd(ro) })
}

/// The image region of one layout generation.
#[derive(Debug)]
pub struct ImageRegion {
    /// Read-only descriptor handed to programs.
    handout: OwnedFd,
    map: Mapping,
    shape: ImageShape,
    generation: u32,
    entries: Vec<Entry>,
}

impl ImageRegion {
    /// A region for `entries` over an image of `image_len` bytes cycled every `period`.
    pub fn create(
        generation: u32,
        entries: Vec<Entry>,
        image_len: usize,
        period: std::time::Duration,
        watchdog: u32,
    ) -> std::io::Result<ImageRegion> {
        let shape = ImageShape {
            image_len,
            entries: entries.len(),
        };
        let fd = memfd(c"ecatd-image", shape.len())?;
        let map = Mapping::map(fd.as_fd(), shape.len(), true)?;
        let handout = read_only(&fd)?;
        let u32_of = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
        map.write_bytes(image::MAGIC, &IMAGE_MAGIC);
        map.store_u32(image::VERSION, shm::VERSION);
        map.store_u32(image::GENERATION, generation);
        map.store_u32(image::IMAGE_LEN, u32_of(image_len));
        map.store_u32(image::ENTRY_COUNT, u32_of(entries.len()));
        map.store_u32(image::ENTRY_SIZE, u32_of(shm::ENTRY_SIZE));
        map.store_u32(image::ENTRIES, u32_of(shm::ENTRIES_OFFSET));
        map.store_u32(image::SLOTS, u32_of(shape.slots()));
        map.store_u32(image::SLOT_STRIDE, u32_of(shape.stride()));
        map.store_u32(image::SLOT_COUNT, shm::SLOTS);
        map.store_u64(
            image::PERIOD_NS,
            u64::try_from(period.as_nanos()).unwrap_or(u64::MAX),
        );
        map.store_u32(image::WATCHDOG, watchdog);
        for (i, entry) in entries.iter().enumerate() {
            map.write_bytes(shm::ENTRIES_OFFSET + i * shm::ENTRY_SIZE, &entry.encode());
        }
        map.store_u32(image::FLAGS, shm::FLAG_LIVE);
        Ok(ImageRegion {
            handout,
            map,
            shape,
            generation,
            entries,
        })
    }

    /// The layout generation.
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// The entries of this generation.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// Bytes of the process image.
    pub fn image_len(&self) -> usize {
        self.shape.image_len
    }

    /// Bytes a program maps.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// The read-only descriptor a program gets.
    pub fn handout(&self) -> std::os::fd::BorrowedFd<'_> {
        self.handout.as_fd()
    }

    /// Publishes cycle `cycle` (bus thread): its slot (stamped with the time of
    /// publication, `CLOCK_MONOTONIC`), then the header's cycle number.
    pub fn publish(&self, cycle: u64, inputs: &[u8], outputs: &[u8], wkc: u16, expected: u16) {
        let len = self.shape.image_len;
        let (Some(inputs), Some(outputs)) = (inputs.get(..len), outputs.get(..len)) else {
            // The image changed size under this region: the layout check replaces it.
            return;
        };
        let slot = shm::slot_of(self.shape.slots(), self.shape.stride(), cycle);
        let mut counters = [0u8; 4];
        counters[..2].copy_from_slice(&wkc.to_le_bytes());
        counters[2..].copy_from_slice(&expected.to_le_bytes());
        let published = monotonic_ns().to_le_bytes();
        shm::write_slot(
            &self.map,
            slot,
            cycle,
            &[
                (8, &counters),
                (shm::slot::PUBLISHED_NS, &published),
                (self.shape.inputs_at(), inputs),
                (self.shape.outputs_at(), outputs),
            ],
        );
        self.map.store_u64(image::CYCLE, cycle);
    }

    /// Records the owner (pid 0: none) for programs to see.
    pub fn set_owner(&self, pid: u32, uid: u32) {
        self.map.store_u32(image::OWNER_PID, pid);
        self.map.store_u32(image::OWNER_UID, uid);
    }

    /// Records the commit number the last frame carried.
    pub fn set_applied(&self, commit: u64) {
        self.map.store_u64(image::APPLIED, commit);
    }

    /// Records the watchdog trips so far.
    pub fn set_trips(&self, trips: u32) {
        self.map.store_u32(image::TRIPS, trips);
    }

    /// Marks the region replaced by a newer generation (and no longer published).
    pub fn mark_stale(&self) {
        self.map.store_u32(image::FLAGS, shm::FLAG_STALE);
    }

    /// Marks the region no longer published (ecatd stopping).
    pub fn mark_dead(&self) {
        self.map.store_u32(image::FLAGS, 0);
    }
}

/// The commit region of one claim.
#[derive(Debug)]
pub struct CommitRegion {
    fd: OwnedFd,
    map: Mapping,
    shape: CommitShape,
}

impl CommitRegion {
    /// A fresh region for commits of `generation`, image of `image_len` bytes.
    pub fn create(generation: u32, image_len: usize) -> std::io::Result<CommitRegion> {
        let shape = CommitShape { image_len };
        let fd = memfd(c"ecatd-commit", shape.len())?;
        let map = Mapping::map(fd.as_fd(), shape.len(), true)?;
        let u32_of = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
        map.write_bytes(commit::MAGIC, &COMMIT_MAGIC);
        map.store_u32(commit::GENERATION, generation);
        map.store_u32(commit::IMAGE_LEN, u32_of(image_len));
        map.store_u32(commit::SLOTS, u32_of(commit::FIRST_SLOT));
        map.store_u32(commit::SLOT_STRIDE, u32_of(shape.stride()));
        map.store_u32(commit::SLOT_COUNT, shm::SLOTS);
        Ok(CommitRegion { fd, map, shape })
    }

    /// The descriptor the owner gets (read-write).
    pub fn handout(&self) -> std::os::fd::BorrowedFd<'_> {
        self.fd.as_fd()
    }

    /// Bytes the owner maps.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// The owner's last commit number.
    pub fn latest(&self) -> u64 {
        self.map.load_u64(commit::COMMIT)
    }

    /// Copies commit `number` into `into` (the image's length) if its slot holds it whole and
    /// the region is still of `generation`; false otherwise (torn, overwritten, or garbage).
    pub fn take(&self, number: u64, generation: u32, into: &mut [u8]) -> bool {
        if self.map.load_u32(commit::GENERATION) != generation || into.len() != self.shape.image_len
        {
            return false;
        }
        let slot = shm::slot_of(commit::FIRST_SLOT, self.shape.stride(), number);
        shm::read_slot(&self.map, slot, number, |m| {
            m.read_bytes(slot + shm::SLOT_HEADER, into);
        })
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use ecat_app::shm::{self, ImageShape, Mapping};

    use super::*;

    #[test]
    fn a_published_slot_carries_the_time_of_its_publication() {
        let region =
            ImageRegion::create(1, Vec::new(), 4, Duration::from_millis(1), 10).expect("region");
        let before = monotonic_ns();
        region.publish(7, &[1, 2, 3, 4], &[0; 4], 3, 3);
        let after = monotonic_ns();
        let map = Mapping::map(region.handout(), region.len(), false).expect("map");
        let shape = ImageShape {
            image_len: 4,
            entries: 0,
        };
        let slot = shm::slot_of(shape.slots(), shape.stride(), 7);
        let mut published = [0u8; 8];
        assert!(shm::read_slot(&map, slot, 7, |m| {
            m.read_bytes(slot + shm::slot::PUBLISHED_NS, &mut published);
        }));
        let published = u64::from_le_bytes(published);
        assert!(
            (before..=after).contains(&published),
            "{before} {published} {after}"
        );
    }
}
