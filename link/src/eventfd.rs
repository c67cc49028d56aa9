//! An eventfd(2) as a wake-up: readable once signalled, until drained. A link without a
//! descriptor of its own can offer one as its [`Link::wait_fd`](crate::Link::wait_fd), and
//! a thread that waits on several descriptors can be woken through one.

use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, FromRawFd, OwnedFd};

/// A non-blocking eventfd, used as a level-triggered wake-up flag.
#[derive(Debug)]
pub struct EventFd(OwnedFd);

impl EventFd {
    /// A new one, not readable.
    pub fn new() -> io::Result<EventFd> {
        // SAFETY: no pointers; a non-negative result is a new descriptor we own.
        let fd = unsafe { libc::eventfd(0, libc::EFD_NONBLOCK | libc::EFD_CLOEXEC) };
        if fd < 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: as above: a fresh descriptor, owned by nothing else.
        Ok(EventFd(unsafe { OwnedFd::from_raw_fd(fd) }))
    }

    /// Makes it readable.
    pub fn signal(&self) {
        let one = 1u64.to_ne_bytes();
        // SAFETY: 8 bytes from a live buffer to our open descriptor. A full counter (EAGAIN)
        // still leaves it readable, which is all a wake-up needs.
        let _ = unsafe { libc::write(self.0.as_raw_fd(), one.as_ptr().cast(), one.len()) };
    }

    /// Makes it unreadable again.
    pub fn drain(&self) {
        let mut count = [0u8; 8];
        // SAFETY: at most 8 bytes into a live buffer from our open, non-blocking descriptor;
        // at zero it fails with EAGAIN, which is fine.
        let _ = unsafe { libc::read(self.0.as_raw_fd(), count.as_mut_ptr().cast(), count.len()) };
    }
}

impl AsFd for EventFd {
    fn as_fd(&self) -> BorrowedFd<'_> {
        self.0.as_fd()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn readable(fd: &EventFd) -> bool {
        crate::which_readable(&[fd.as_fd()], Duration::ZERO).unwrap()[0]
    }

    #[test]
    fn readable_from_the_signal_to_the_drain() {
        let fd = EventFd::new().unwrap();
        assert!(!readable(&fd));
        fd.signal();
        fd.signal();
        assert!(readable(&fd));
        fd.drain();
        assert!(!readable(&fd));
        // Draining an unsignalled one is harmless.
        fd.drain();
        assert!(!readable(&fd));
    }
}
