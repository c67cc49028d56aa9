//! The datagram loop: one thread owns the link and moves every datagram of the master.
//!
//! [`Bus::start`] spawns the bus thread around a [`Link`] and returns a [`BusHandle`].
//! Any thread or async task submits datagrams through a handle and gets a [`Pending`]
//! back, which it can `.await` (never blocking a runtime thread) or [`wait`](Pending::wait)
//! for. The bus thread:
//!
//! - packs datagrams from many callers into as few frames as the MTU allows, keeping
//!   [groups](BusHandle::submit_group) together in one frame;
//! - tags each datagram with an index (0..=255) that is never reused while a frame
//!   carrying it is in flight;
//! - matches each returned frame to the frame it answers by index *and* by the command,
//!   address and length of every datagram, so a late, duplicated or foreign frame is
//!   counted and ignored, never delivered to the wrong caller (see `matching`);
//! - sends a frame again when no reply came before [`BusConfig::response_timeout`], up to
//!   [`BusConfig::retries`] times, under the same indices (a late reply to an earlier
//!   attempt completes it), then fails its datagrams with [`BusError::Timeout`];
//! - checks the working counter against what the caller expected ([`WkcCheck`]);
//! - runs a [`CyclicTask`] at a fixed period, its frame going ahead of acyclic traffic;
//! - keeps lock-free statistics ([`BusStatsSnapshot`]), including round-trip times.
//!
//! # Example
//!
//! ```
//! use std::time::{Duration, Instant};
//!
//! use master_core::bus::{Bus, BusConfig};
//! use master_core::link::{Link, MAX_FRAME_LEN, MemoryLink, Wait};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let (near, mut far) = MemoryLink::pair(8);
//! // A stand-in for a segment without slaves: every frame comes straight back.
//! let segment = std::thread::spawn(move || {
//!     let mut buf = [0u8; MAX_FRAME_LEN];
//!     let patience = || Wait::Until(Instant::now() + Duration::from_secs(5));
//!     while let Ok(Some(len)) = far.recv(&mut buf, patience()) {
//!         let _ = far.send(&buf[..len]);
//!     }
//! });
//! let link: Box<dyn Link> = Box::new(near);
//! let (bus, thread) = Bus::start(link, BusConfig::default())?;
//! // From a blocking thread; an async task would write `bus.brd(0x0000, 2).await`.
//! let reply = bus.brd(0x0000, 2).wait()?;
//! assert_eq!(reply.wkc, 0, "no slave counted itself");
//! assert_eq!(bus.stats().frames_received, 1);
//! drop(bus); // the last handle: the bus stops
//! drop(thread.join()); // and hands back the link, dropped here, which ends the stand-in
//! segment.join().unwrap();
//! # Ok(())
//! # }
//! ```
//!
//! # Retries and idempotency
//!
//! A frame can be lost on the way out (no slave saw it) or on the way back (every slave
//! processed it). The master cannot tell which, and resends in both cases, so **a retried
//! write may be carried out twice**. For registers this is harmless (the same value is
//! written again). For a mailbox it is not: a repeated mailbox write would deliver the same
//! request twice, and a repeated read of the send mailbox could swallow a reply. The
//! mailbox layer therefore guards every transaction with the mailbox counter (1..7,
//! spec-notes §mbx.counter) and the repeat procedure (spec-notes §mbx.repeat) rather than relying on the bus, and reads
//! the send mailbox with [`BusHandle::submit_once`], which fails a lost datagram instead
//! of sending it again. The same
//! goes for a datagram that fails with [`BusError::Timeout`] or [`BusError::Shutdown`]
//! after it was sent: it may or may not have been carried out.
//!
//! # Waiting
//!
//! With [`WaitMode::Poll`] the bus thread sleeps in the link's `recv` while frames are out
//! (in slices of at most 1 ms, since nothing can wake a link from outside: a shutdown, a
//! new cyclic task or datagrams waiting for a free frame record are seen within that), and
//! on a condition variable while idle, where a submission wakes it at once. With
//! [`WaitMode::BusyPoll`] it never sleeps: it spins on the link while frames are out and
//! yields to other runnable threads between checks while idle. Configure the link to match
//! (a raw socket's `busy_poll` option).
//!
//! # Priority
//!
//! A due cycle goes first: the cyclic frame is sent before any waiting acyclic frame, and
//! 16 of the 256 datagram indices are kept out of reach of acyclic traffic so that a burst
//! of it cannot hold process data up. An acyclic frame is sent only if its recent round
//! trip ends before the next cycle is due (up to a quarter of the period); otherwise it
//! waits for the cyclic frame ([`BusStatsSnapshot::acyclic_held`]). The bus thread sets its
//! timer slack to the minimum, so that its timed wake-ups are not batched late, and asks
//! for `SCHED_FIFO` when configured to ([`BusConfig::priority`]); CPU pinning is left to
//! the caller (for example `taskset` on the process). With [`BusConfig::cycle_spin`] it
//! wakes that long before each cycle and spins until the cycle is due, so that the
//! kernel's wake-up latency is spent before the cycle instead of after.
//!
//! # Guests
//!
//! A [`Guest`] ([`BusHandle::set_guest`]) is work the bus thread does for another part of
//! the master between its frames: it waits on the guest's descriptor in the same
//! `ppoll(2)` as the link (while idle, beside the submission queue's eventfd instead of the
//! condition variable) and gives it a bounded turn after each wait, told when the next
//! cycle is due. The mailbox gateway serves its UDP socket this way, so that a client's
//! request wakes only the thread that sends its frame. Only a bus whose link has a
//! [`Link::wait_fd`] and that sleeps ([`WaitMode::Poll`]) takes one.
//!
//! # Memory
//!
//! All buffers of the bus thread are allocated when it starts; the loop itself does not
//! allocate (a guest's turn may: that is the guest's own work). A caller's request allocates its completion slot, and its data only when
//! longer than [`INLINE_LEN`] bytes; the reply is copied into that same storage.

use std::io;
use std::sync::Arc;
use std::thread::JoinHandle;

use crate::link::Link;

mod chain;
mod completion;
mod config;
mod cyclic;
mod data;
mod engine;
mod error;
/// The frame matcher driven by arbitrary bytes, for the fuzz target `frame_matcher`.
#[doc(hidden)]
pub mod fuzzing;
mod guest;
mod handle;
mod histogram;
mod index;
mod matching;
mod queue;
mod record;
pub mod redundancy;
mod request;
mod sched;
mod stamp;
mod stats;

pub use chain::{ChainFeed, Chained};
pub use completion::{DatagramResult, Pending};
pub use config::{BusConfig, WaitMode};
pub use cyclic::{CyclicFrame, CyclicReply, CyclicTask, DEFAULT_PERIOD, MIN_PERIOD};
pub use data::{DatagramData, INLINE_LEN};
pub use error::BusError;
pub use guest::Guest;
pub use handle::BusHandle;
pub(crate) use histogram::Histogram;
pub use histogram::HistogramSnapshot;
pub use request::{DatagramRequest, DatagramResponse, WkcCheck};
pub(crate) use sched::set_min_timer_slack;
pub use sched::{ThreadPriority, calling_thread_realtime};
pub use stamp::Stamp;
pub use stats::BusStatsSnapshot;

/// What the handles and the bus thread share.
pub(crate) struct Shared {
    pub queue: queue::Submissions,
    pub stats: stats::BusStats,
    pub config: BusConfig,
    /// What the ring link knows, when the bus runs on a ring.
    pub ring: Option<redundancy::RingWatch>,
    /// The link has a [`Link::wait_fd`], so a [`Guest`] can wait beside it.
    pub waitable: bool,
}

/// Starts buses; see [`Bus::start`].
#[derive(Debug)]
pub struct Bus(());

impl Bus {
    /// Spawns the bus thread (named `ecat-bus`), which owns `link` from now on.
    ///
    /// Returns a handle to submit datagrams and the thread's join handle, which yields the
    /// link back once the bus has shut down (after [`BusHandle::shutdown`] or when the last
    /// handle is dropped), so that a test can look into it or a master reuse it.
    ///
    /// Fails with `InvalidInput` for an unusable configuration, or if the thread cannot be
    /// spawned.
    pub fn start<L: Link + 'static>(
        link: L,
        config: BusConfig,
    ) -> io::Result<(BusHandle, JoinHandle<L>)> {
        Self::spawn(link, config, None)
    }

    /// [`Bus::start`] on a ring (cable redundancy): every frame goes out of `primary` and
    /// `backup`, and the two copies come back as one ([`redundancy`]). Frames are built
    /// [`redundancy::RING_OVERHEAD`] bytes shorter than `config.max_frame_len` to leave
    /// room for the ring's probe; a returned copy waits at most `grace` for its twin
    /// ([`redundancy::DEFAULT_GRACE`] suits a real ring; an in-process one returns both at
    /// once and can use zero). [`BusHandle::ring`] tells how the ring is.
    pub fn start_ring<P: Link + 'static, B: Link + 'static>(
        primary: P,
        backup: B,
        config: BusConfig,
        grace: std::time::Duration,
    ) -> io::Result<(BusHandle, JoinHandle<redundancy::RingLink<P, B>>)> {
        let link = redundancy::RingLink::new(primary, backup, grace);
        let watch = link.watch();
        let config = BusConfig {
            max_frame_len: config
                .max_frame_len
                .min(crate::wire::ethernet::MAX_FRAME_LEN)
                .saturating_sub(redundancy::RING_OVERHEAD),
            ..config
        };
        Self::spawn(link, config, Some(watch))
    }

    fn spawn<L: Link + 'static>(
        link: L,
        config: BusConfig,
        ring: Option<redundancy::RingWatch>,
    ) -> io::Result<(BusHandle, JoinHandle<L>)> {
        config.check()?;
        let shared = Arc::new(Shared {
            queue: queue::Submissions::new(config.queue_capacity),
            stats: stats::BusStats::default(),
            config,
            ring,
            waitable: link.wait_fd().is_some(),
        });
        let engine = engine::Engine::new(link, Arc::clone(&shared));
        let thread = std::thread::Builder::new()
            .name("ecat-bus".into())
            .spawn(move || {
                let sleeps = config.wait_mode == WaitMode::Poll;
                let realtime = sched::apply(config.priority, sleeps);
                engine.set_scheduling(realtime, sched::own_time_slice_ns());
                engine.run()
            })?;
        Ok((BusHandle::new(shared), thread))
    }
}
