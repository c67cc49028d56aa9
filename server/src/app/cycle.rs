//! The bus thread's side of the application interface: a [`CycleHook`] that publishes every
//! completed cycle into the current image region and wakes the attached programs, and
//! before every frame takes the owner's newest whole commit (or the safe outputs) into the
//! image and keeps the watchdog.
//!
//! The state is behind one mutex that the server's tasks hold only to swap a value (never
//! across an await or a system call), so the bus thread never waits on a program.

use std::os::fd::{AsRawFd, OwnedFd};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use master_core::master::{CompletedCycle, CycleHook, OutgoingImage};

use super::region::{CommitRegion, ImageRegion};

/// Who owns the outputs, as the bus thread sees it.
#[derive(Debug)]
struct Owner {
    session: u64,
    commits: Arc<CommitRegion>,
    /// The last commit number taken into the image.
    applied: u64,
    /// Frames built since then.
    idle: u32,
}

#[derive(Debug, Default)]
struct State {
    region: Option<Arc<ImageRegion>>,
    /// The master's layout count `region` was made for; cycles of another layout are
    /// neither published nor given the owner's outputs.
    layout: u64,
    /// The layout count the bus thread saw last.
    seen_layout: u64,
    owner: Option<Owner>,
    /// The safe outputs of `region`'s layout (the whole image).
    safe: Vec<u8>,
    /// Write `safe` into the next frame.
    put_safe: bool,
    /// Where a commit is copied before it goes into the image (sized with the region).
    scratch: Vec<u8>,
    /// Each attached program's eventfd.
    wakers: Vec<Arc<OwnedFd>>,
    watchdog: u32,
    /// The session whose ownership the watchdog ended, for the server to tell.
    tripped: Option<u64>,
    /// Outputs forced from the APIs, written into every frame.
    forces: Vec<Force>,
}

/// An output forced from the APIs: its value goes into every frame until released.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Force {
    /// The entry.
    pub entry: ecat_app::entry::Entry,
    /// Its raw bits.
    pub value: u64,
    /// Who forced it (the token's name).
    pub by: String,
    /// Whether it was forced over an owner's outputs.
    pub over_owner: bool,
    /// When, seconds since the Unix epoch.
    pub since: u64,
}

/// The hook and the server's handle on it (shared).
#[derive(Debug, Default)]
pub struct CycleShare {
    state: Mutex<State>,
    /// Wakes the server's task: the layout changed or the watchdog tripped.
    notice: tokio::sync::Notify,
    trips: AtomicU64,
    commits: AtomicU64,
    cycles: AtomicU64,
}

impl CycleShare {
    /// A share with no region yet and the owner's watchdog of `watchdog` cycles.
    pub fn new(watchdog: u32) -> CycleShare {
        let share = CycleShare::default();
        share.lock().watchdog = watchdog;
        share
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Publishes into `region` from now on, for the master's layout `layout`, with `safe` as
    /// the safe outputs. An owner of the previous region loses the outputs (returned: its
    /// session), and the safe outputs go into the next frame.
    pub fn install(&self, region: Arc<ImageRegion>, layout: u64, safe: Vec<u8>) -> Option<u64> {
        let mut st = self.lock();
        st.scratch = vec![0; region.image_len()];
        if let Some(old) = st.region.replace(region) {
            old.mark_stale();
        }
        st.layout = layout;
        st.safe = safe;
        // A force names bits of the old layout: it does not survive a new one.
        st.forces.clear();
        let lost = st.owner.take().map(|o| o.session);
        st.put_safe |= lost.is_some();
        lost
    }

    /// The layout count is still `layout` but the region was found good for `newer`.
    pub fn accept_layout(&self, newer: u64) {
        self.lock().layout = newer;
    }

    /// The master's layout count the bus thread saw, if it differs from the region's.
    pub fn layout_pending(&self) -> Option<u64> {
        let st = self.lock();
        (st.seen_layout != st.layout).then_some(st.seen_layout)
    }

    /// The current region.
    pub fn region(&self) -> Option<Arc<ImageRegion>> {
        self.lock().region.clone()
    }

    /// Gives the outputs to `session`, its commits in `commits`; refused with the owner's
    /// session when another holds them.
    pub fn claim(&self, session: u64, commits: Arc<CommitRegion>) -> Result<(), u64> {
        let mut st = self.lock();
        if let Some(owner) = &st.owner {
            return Err(owner.session);
        }
        st.owner = Some(Owner {
            session,
            applied: commits.latest(),
            commits,
            idle: 0,
        });
        Ok(())
    }

    /// Takes the outputs back from `session` if it holds them (the safe outputs go into
    /// the next frame); whether it held them.
    pub fn release(&self, session: u64) -> bool {
        let mut st = self.lock();
        if st.owner.as_ref().is_none_or(|o| o.session != session) {
            return false;
        }
        st.owner = None;
        st.put_safe = true;
        true
    }

    /// Ends any ownership and puts the safe outputs into the next frame (ecatd stopping).
    pub fn release_all(&self) -> Option<u64> {
        let mut st = self.lock();
        st.put_safe = true;
        st.owner.take().map(|o| o.session)
    }

    /// Forces `force` (replacing a force of the same entry); written from the next frame on.
    pub fn force(&self, force: Force) {
        let mut st = self.lock();
        st.forces.retain(|f| f.entry != force.entry);
        st.forces.push(force);
    }

    /// Releases the force of `entry`; whether there was one.
    pub fn release_force(&self, entry: &ecat_app::entry::Entry) -> bool {
        let mut st = self.lock();
        let before = st.forces.len();
        st.forces.retain(|f| &f.entry != entry);
        st.forces.len() != before
    }

    /// The forced outputs.
    pub fn forces(&self) -> Vec<Force> {
        self.lock().forces.clone()
    }

    /// The session owning the outputs.
    pub fn owner_session(&self) -> Option<u64> {
        self.lock().owner.as_ref().map(|o| o.session)
    }

    /// The session whose ownership the watchdog ended since the last call.
    pub fn take_trip(&self) -> Option<u64> {
        self.lock().tripped.take()
    }

    /// Wakes `fd` (an eventfd) at every published cycle.
    pub fn add_waker(&self, fd: Arc<OwnedFd>) {
        self.lock().wakers.push(fd);
    }

    /// No longer wakes `fd`.
    pub fn remove_waker(&self, fd: &Arc<OwnedFd>) {
        self.lock().wakers.retain(|w| !Arc::ptr_eq(w, fd));
    }

    /// Waits until the bus thread has something for the server.
    pub async fn noticed(&self) {
        self.notice.notified().await;
    }

    /// Watchdog trips so far.
    pub fn trips(&self) -> u64 {
        self.trips.load(Ordering::Relaxed)
    }

    /// Commits taken into the image so far.
    pub fn commits(&self) -> u64 {
        self.commits.load(Ordering::Relaxed)
    }

    /// Cycles published so far.
    pub fn cycles(&self) -> u64 {
        self.cycles.load(Ordering::Relaxed)
    }

    fn put(outputs: &mut [u8], image: &[u8]) {
        if let Some(target) = outputs.get_mut(..image.len()) {
            target.copy_from_slice(image);
        }
    }

    /// Takes the owner's newest whole commit into the frame, or counts the owner's
    /// watchdog and trips it.
    fn owners_outputs(&self, st: &mut State, image: &mut OutgoingImage<'_>) {
        let Some(owner) = &mut st.owner else {
            return;
        };
        let generation = st.region.as_ref().map_or(0, |r| r.generation());
        let latest = owner.commits.latest();
        if latest != owner.applied && owner.commits.take(latest, generation, &mut st.scratch) {
            Self::put(image.outputs, &st.scratch);
            owner.applied = latest;
            owner.idle = 0;
            self.commits.fetch_add(1, Ordering::Relaxed);
            if let Some(region) = &st.region {
                region.set_applied(latest);
            }
            return;
        }
        owner.idle = owner.idle.saturating_add(1);
        if owner.idle >= st.watchdog {
            st.tripped = Some(owner.session);
            st.owner = None;
            Self::put(image.outputs, &st.safe);
            let trips = self.trips.fetch_add(1, Ordering::Relaxed) + 1;
            if let Some(region) = &st.region {
                region.set_owner(0, 0);
                region.set_trips(u32::try_from(trips).unwrap_or(u32::MAX));
            }
            self.notice.notify_one();
        }
    }
}

impl CycleHook for CycleShare {
    fn before_send(&self, image: &mut OutgoingImage<'_>) {
        let mut st = self.lock();
        let st = &mut *st;
        if st.seen_layout != image.layout {
            st.seen_layout = image.layout;
            self.notice.notify_one();
        }
        if image.layout != st.layout {
            // The offsets may have moved: nothing computed for the old layout goes out.
            return;
        }
        if st.put_safe {
            st.put_safe = false;
            Self::put(image.outputs, &st.safe);
        }
        self.owners_outputs(st, image);
        // A forced entry wins over the owner and the safe value, every frame.
        for force in &st.forces {
            force.entry.set(image.outputs, force.value);
        }
    }

    fn after_receive(&self, cycle: &CompletedCycle<'_>) {
        let st = self.lock();
        if cycle.layout != st.layout {
            return;
        }
        let Some(region) = &st.region else {
            return;
        };
        region.publish(
            cycle.cycle,
            cycle.inputs,
            cycle.outputs,
            cycle.wkc,
            cycle.expected_wkc,
        );
        self.cycles.fetch_add(1, Ordering::Relaxed);
        let one = 1u64.to_ne_bytes();
        for waker in &st.wakers {
            // Non-blocking; an eventfd only refuses at a count near 2^64.
            // SAFETY: writes 8 bytes from a live buffer to an fd the share keeps open.
            unsafe { libc::write(waker.as_raw_fd(), one.as_ptr().cast(), one.len()) };
        }
    }
}

#[cfg(test)]
mod tests {
    use std::os::fd::AsFd;
    use std::time::Duration;

    use ecat_app::entry::{Direction, Entry};
    use ecat_app::shm::{self, Mapping, commit, image};

    use super::*;

    fn region(generation: u32) -> Arc<ImageRegion> {
        let entry = Entry {
            position: 1,
            station: 1002,
            pdo: 0x1600,
            index: 0x7000,
            subindex: 1,
            direction: Direction::Out,
            data_type: 1,
            bit_offset: 0,
            bit_length: 1,
            name: "Output 1".into(),
        };
        Arc::new(
            ImageRegion::create(generation, vec![entry], 4, Duration::from_millis(1), 10)
                .expect("region"),
        )
    }

    /// What an owner does: writes commit `number` of `data` into the region it was given.
    fn commit_as_owner(commits: &CommitRegion, number: u64, data: &[u8]) {
        let map = Mapping::map(commits.handout(), commits.len(), true).expect("map");
        let stride = shm::CommitShape { image_len: 4 }.stride();
        let slot = shm::slot_of(commit::FIRST_SLOT, stride, number);
        shm::write_slot(&map, slot, number, &[(shm::SLOT_HEADER, data)]);
        map.store_u64(commit::COMMIT, number);
    }

    fn frame(share: &CycleShare, layout: u64, outputs: &mut [u8]) {
        share.before_send(&mut OutgoingImage {
            layout,
            cycle: 0,
            outputs,
        });
    }

    fn owned() -> (CycleShare, Arc<CommitRegion>) {
        let share = CycleShare::new(10);
        assert_eq!(share.install(region(1), 7, vec![0, 0, 0x02, 0]), None);
        let commits = Arc::new(CommitRegion::create(1, 4).expect("commit region"));
        share.claim(42, Arc::clone(&commits)).expect("free");
        (share, commits)
    }

    #[test]
    fn a_commit_goes_out_whole_and_the_watchdog_trips_after_its_cycles() {
        let (share, commits) = owned();
        let mut outputs = [0u8; 4];
        commit_as_owner(&commits, 1, &[1, 2, 3, 4]);
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [1, 2, 3, 4]);
        assert_eq!(share.region().unwrap().len() % 4096, 0);
        // Nine frames without a commit: the outputs stay the owner's.
        for _ in 0..9 {
            frame(&share, 7, &mut outputs);
            assert_eq!(outputs, [1, 2, 3, 4]);
            assert_eq!(share.take_trip(), None);
        }
        // The tenth: the safe outputs go into this very frame.
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [0, 0, 0x02, 0]);
        assert_eq!(share.take_trip(), Some(42));
        assert_eq!(share.trips(), 1);
        assert_eq!(share.owner_session(), None);
        // A later commit of the old owner changes nothing.
        commit_as_owner(&commits, 2, &[9, 9, 9, 9]);
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [0, 0, 0x02, 0]);
        // Anyone may claim now.
        assert!(
            share
                .claim(43, Arc::new(CommitRegion::create(1, 4).unwrap()))
                .is_ok()
        );
    }

    #[test]
    fn a_second_claim_is_refused_with_the_owners_session() {
        let (share, _commits) = owned();
        let other = Arc::new(CommitRegion::create(1, 4).unwrap());
        assert_eq!(share.claim(43, other), Err(42));
        assert!(!share.release(43), "only the owner releases");
        assert!(share.release(42));
        let mut outputs = [7u8; 4];
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [0, 0, 0x02, 0], "released: the safe outputs once");
        outputs = [5; 4];
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [5; 4], "and then the image is left alone");
    }

    #[test]
    fn a_torn_or_foreign_commit_is_not_taken() {
        let (share, commits) = owned();
        let mut outputs = [0u8; 4];
        // The header names commit 2, but its slot holds commit 5's stamp (torn, or garbage).
        commit_as_owner(&commits, 5, &[5, 5, 5, 5]);
        let map = Mapping::map(commits.handout(), commits.len(), true).unwrap();
        map.store_u64(commit::COMMIT, 2);
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [0; 4]);
        // A commit region rewritten for another generation is ignored.
        map.store_u32(commit::GENERATION, 2);
        commit_as_owner(&commits, 3, &[3, 3, 3, 3]);
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [0; 4]);
        map.store_u32(commit::GENERATION, 1);
        commit_as_owner(&commits, 4, &[4, 4, 4, 4]);
        frame(&share, 7, &mut outputs);
        assert_eq!(outputs, [4; 4]);
    }

    #[test]
    fn another_layout_stops_the_commits_and_the_cycles_until_it_is_accepted() {
        let (share, commits) = owned();
        let mut outputs = [0u8; 4];
        commit_as_owner(&commits, 1, &[1, 1, 1, 1]);
        frame(&share, 8, &mut outputs);
        assert_eq!(
            outputs, [0; 4],
            "nothing computed for layout 7 goes out in layout 8"
        );
        assert_eq!(share.layout_pending(), Some(8));
        let cycle = CompletedCycle {
            layout: 8,
            cycle: 5,
            inputs: &[1, 2, 3, 4],
            outputs: &[0; 4],
            wkc: 3,
            expected_wkc: 3,
        };
        share.after_receive(&cycle);
        assert_eq!(share.cycles(), 0);
        share.accept_layout(8);
        assert_eq!(share.layout_pending(), None);
        frame(&share, 8, &mut outputs);
        assert_eq!(outputs, [1; 4]);
        share.after_receive(&cycle);
        assert_eq!(share.cycles(), 1);
    }

    #[test]
    fn a_completed_cycle_is_published_and_wakes_every_program() {
        let share = CycleShare::new(10);
        share.install(region(1), 1, vec![0; 4]);
        // SAFETY: plain flags, result checked.
        let fd = unsafe { libc::eventfd(0, libc::EFD_NONBLOCK) };
        assert!(fd >= 0);
        // SAFETY: just created, ours.
        let waker = Arc::new(unsafe { <OwnedFd as std::os::fd::FromRawFd>::from_raw_fd(fd) });
        share.add_waker(Arc::clone(&waker));
        for cycle in 1..=4 {
            share.after_receive(&CompletedCycle {
                layout: 1,
                cycle,
                inputs: &[cycle as u8, 0xAA, 0, 0],
                outputs: &[0x55, 0, 0, 0],
                wkc: 3,
                expected_wkc: 3,
            });
        }
        let mut count = [0u8; 8];
        // SAFETY: reads 8 bytes into a live buffer.
        assert_eq!(unsafe { libc::read(fd, count.as_mut_ptr().cast(), 8) }, 8);
        assert_eq!(u64::from_ne_bytes(count), 4, "one wake-up per cycle");
        let region = share.region().unwrap();
        let map = Mapping::map(region.handout(), region.len(), false).unwrap();
        assert_eq!(map.load_u64(image::CYCLE), 4);
        let shape = shm::ImageShape {
            image_len: 4,
            entries: 1,
        };
        let slot = shm::slot_of(shape.slots(), shape.stride(), 4);
        let (mut inputs, mut sent) = ([0u8; 4], [0u8; 4]);
        assert!(shm::read_slot(&map, slot, 4, |m| {
            m.read_bytes(slot + shape.inputs_at(), &mut inputs);
            m.read_bytes(slot + shape.outputs_at(), &mut sent);
        }));
        assert_eq!((inputs, sent), ([4, 0xAA, 0, 0], [0x55, 0, 0, 0]));
        share.remove_waker(&waker);
        share.after_receive(&CompletedCycle {
            layout: 1,
            cycle: 5,
            inputs: &[0; 4],
            outputs: &[0; 4],
            wkc: 3,
            expected_wkc: 3,
        });
        // SAFETY: reads 8 bytes into a live buffer.
        let again = unsafe { libc::read(fd, count.as_mut_ptr().cast(), 8) };
        assert_eq!(again, -1, "not woken");
        let _ = waker.as_fd();
    }
}
