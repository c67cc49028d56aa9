//! Sending and receiving raw Ethernet frames: the one place where ecatd touches a network.
//!
//! Everything above this layer sees a [`Link`]: something that sends a complete Ethernet frame
//! (destination MAC through the last payload byte, no FCS) and receives one into a caller's
//! buffer, waiting at most until a deadline. The bus thread owns exactly one link and drives it
//! in a loop, so the trait is deliberately small, synchronous and allocation-free.
//!
//! Implementations:
//! - [`RawSocket`]: an `AF_PACKET` socket on a Linux network interface (the real bus).
//! - [`MemoryLink`]: two in-process ends joined by bounded queues (tests, the simulator).
//!
//! Wrappers, which take any link and are links themselves (so they stack, like smoltcp's
//! device middleware):
//! - [`PcapTap`]: writes every frame in both directions to a pcap file for Wireshark.
//! - [`FaultInjector`]: drops, corrupts and delays frames, repeatably from a seed.
//! - [`CaptureTap`]: copies frames to a live capture on request, off the bus thread.
//!
//! [`netdev`] holds the kernel's network-device controls (names, link up, MAC, IPv4, TAP)
//! shared with ecatd's EoE interfaces and the simulator's EoE bridge.
//!
//! A link does not pad short frames to the Ethernet minimum and does not filter by MAC
//! address: padding is the frame builder's job, and EtherCAT slaves may rewrite the source
//! address of returning frames, so only the EtherType can be trusted to pick our traffic.

use std::io;
use std::os::fd::BorrowedFd;
use std::time::Instant;

mod capture;
mod eventfd;
mod fault;
mod memory;
pub mod netdev;
mod pcap;
mod raw_socket;

pub use capture::{Capture, CaptureHub, CaptureTap, CapturedFrame};
pub use eventfd::EventFd;
pub use fault::{FaultConfig, FaultCounts, FaultInjector};
pub use memory::MemoryLink;
pub use pcap::PcapTap;
pub use raw_socket::{RawSocket, RawSocketOptions, wait_any_readable, which_readable};

use ecat_wire::ethernet;

/// The largest frame a link is expected to carry: a 1500-byte payload behind a VLAN-tagged
/// Ethernet header (14 + 4 + 1500), without FCS. (The EtherType, header lengths and the
/// untagged maximum are `wire::ethernet`'s.)
///
/// A receive buffer of this size never truncates an EtherCAT frame.
pub const MAX_FRAME_LEN: usize =
    ethernet::MAX_FRAME_LEN + (ethernet::VLAN_HEADER_LEN - ethernet::HEADER_LEN);

/// How long [`Link::recv`] may wait for a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wait {
    /// Return at once: a frame that is already queued, or nothing.
    NoWait,
    /// Wait for a frame until this instant at the latest. An instant in the past behaves like
    /// [`Wait::NoWait`].
    Until(Instant),
}

impl Wait {
    /// The deadline, if there is one.
    pub fn deadline(self) -> Option<Instant> {
        match self {
            Wait::NoWait => None,
            Wait::Until(deadline) => Some(deadline),
        }
    }

    /// Whether no more waiting is allowed at `now`.
    pub fn expired_at(self, now: Instant) -> bool {
        match self {
            Wait::NoWait => true,
            Wait::Until(deadline) => now >= deadline,
        }
    }
}

/// A network link that carries complete Ethernet frames (without FCS).
///
/// Implementations must not allocate per frame: the bus calls these methods once per frame
/// in its real-time loop.
pub trait Link: Send {
    /// Sends one frame: destination MAC, source MAC, EtherType, payload (already padded to
    /// the Ethernet minimum by the caller if the medium needs it).
    ///
    /// `Ok` means the frame was handed to the medium, not that anyone received it: like a
    /// wire, a link may lose frames silently.
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;

    /// Receives one frame into `buf`, waiting as `wait` allows.
    ///
    /// Returns `Ok(Some(len))` with the frame in `buf[..len]`, or `Ok(None)` if no frame
    /// arrived in time. A frame longer than `buf` is cut to `buf.len()` bytes (a buffer of
    /// [`MAX_FRAME_LEN`] bytes never cuts one); frames are never merged or split.
    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>>;

    /// A file descriptor that becomes readable when [`Link::recv`] has a frame to give,
    /// for a caller that waits on two links at once (cable redundancy waits on its primary
    /// and backup ports in one `ppoll(2)`). `None` (the default) for a link that cannot be
    /// waited on that way; such a caller then takes turns on the links instead.
    fn wait_fd(&self) -> Option<BorrowedFd<'_>> {
        None
    }
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        (**self).send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        (**self).recv(buf, wait)
    }

    fn wait_fd(&self) -> Option<BorrowedFd<'_>> {
        (**self).wait_fd()
    }
}

impl<L: Link + ?Sized> Link for &mut L {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        (**self).send(frame)
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        (**self).recv(buf, wait)
    }

    fn wait_fd(&self) -> Option<BorrowedFd<'_>> {
        (**self).wait_fd()
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn wait_expires_at_its_deadline_and_no_wait_at_once() {
        let now = Instant::now();
        let later = now + Duration::from_millis(5);
        assert!(Wait::NoWait.expired_at(now));
        assert!(!Wait::Until(later).expired_at(now));
        assert!(Wait::Until(later).expired_at(later));
        assert_eq!(Wait::Until(later).deadline(), Some(later));
        assert_eq!(Wait::NoWait.deadline(), None);
    }

    #[test]
    fn the_largest_frame_holds_a_vlan_tagged_full_payload() {
        assert_eq!(MAX_FRAME_LEN, 1518);
    }
}
