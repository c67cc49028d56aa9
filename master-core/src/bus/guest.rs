//! Work the bus thread does for another part of the master between its frames: a guest
//! waits on one file descriptor, in the same `ppoll(2)` as the link, and takes its turn
//! after each of the loop's waits. The mailbox gateway is one (`gateway::on_bus`): a
//! client's datagram then wakes the thread that sends its frame, and the answer is sent
//! from the thread that received it, with no other thread woken in between.

use std::os::fd::BorrowedFd;
use std::time::Instant;

/// What the bus thread runs between its frames: see the [bus's documentation](super#guests).
pub trait Guest: Send {
    /// Readable while the guest has work: its sockets, its own wake-up.
    fn wait_fd(&self) -> BorrowedFd<'_>;

    /// Whether the guest has work it knows of without a system call (a task woken on the
    /// bus thread, which does not make [`Self::wait_fd`] readable): the bus then does not
    /// sleep before the next turn.
    fn has_work(&self) -> bool;

    /// Does what is ready, a bounded amount of it, and stops by `until` (the next cycle's
    /// frame, which waits meanwhile) if it can. `readable` says the bus saw
    /// [`Self::wait_fd`] readable in its last wait; without it, only the work the guest
    /// knows of without a system call is due (tasks woken on the bus thread). A guest that
    /// leaves work undone keeps its descriptor readable, so that the bus comes back to it
    /// at once, after the cycle.
    fn turn(&mut self, readable: bool, until: Option<Instant>);
}
