//! The UDP transport served by the bus thread itself (a [`Guest`] of the bus): a client's
//! datagram wakes the thread that will send its frame, its request's task is polled there,
//! and its answer leaves from there, so no other thread is woken on a request's way
//! (docs/performance.md, "Where the time goes").
//!
//! The request's code is the same as on a worker ([`admit`], [`serve`]); only the executor
//! differs: a small one of this file's own, whose tasks are polled in the bus thread's
//! turns, a bounded number per turn. Timers and anything a task spawns stay with the
//! gateway's first worker's runtime (entered here), whose thread a timer that fires wakes;
//! a task woken from another thread makes the guest's descriptor readable, which ends the
//! bus thread's wait.

use std::collections::VecDeque;
use std::future::Future;
use std::io;
use std::net::UdpSocket;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, FromRawFd, OwnedFd};
use std::panic::AssertUnwindSafe;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll, Wake, Waker};
use std::time::Instant as StdInstant;

use crate::bus::Guest;
use crate::link::EventFd;

use super::service::{Admitted, ReplyTo, Shared, admit, screened, serve};

/// Datagrams read from each socket in one turn, at most.
const RECEIVE_PER_TURN: usize = 16;
/// Task polls in one turn, at most.
const POLLS_PER_TURN: usize = 128;
/// The largest UDP payload (as `udp`: a datagram is read whole, so that an oversized one is
/// seen as such).
const RECEIVE_BUFFER: usize = 65_536;

type Task = Pin<Box<dyn Future<Output = ()> + Send>>;

thread_local! {
    /// On the bus thread, the address of its guest's [`Ready`] (set at every turn): a task
    /// of that guest woken there is polled in the same loop, before the thread waits again
    /// ([`Guest::has_work`]), and needs no wake-up. 0 on every other thread.
    static SERVING: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Whether the calling thread is a bus thread serving a gateway (its request tasks run
/// there).
pub(crate) fn serving() -> bool {
    SERVING.with(std::cell::Cell::get) != 0
}

/// The tasks woken and not yet polled, and the descriptor that says so to the bus.
struct Ready {
    ids: Mutex<VecDeque<usize>>,
    /// Whether `ids` holds any, readable without the lock ([`Guest::has_work`]).
    any: AtomicBool,
    eventfd: EventFd,
}

impl Ready {
    fn push(&self, id: usize) {
        let mut ids = self.ids.lock().unwrap_or_else(PoisonError::into_inner);
        ids.push_back(id);
        self.any.store(true, Ordering::Release);
        drop(ids);
        if SERVING.with(std::cell::Cell::get) != std::ptr::from_ref(self).addr() {
            self.eventfd.signal();
        }
    }

    fn pop(&self) -> Option<usize> {
        let mut ids = self.ids.lock().unwrap_or_else(PoisonError::into_inner);
        let id = ids.pop_front();
        self.any.store(!ids.is_empty(), Ordering::Release);
        id
    }

    fn is_empty(&self) -> bool {
        !self.any.load(Ordering::Acquire)
    }

    fn len(&self) -> usize {
        self.ids
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len()
    }
}

struct TaskWaker {
    id: usize,
    ready: Arc<Ready>,
}

impl Wake for TaskWaker {
    fn wake(self: Arc<Self>) {
        self.ready.push(self.id);
    }

    fn wake_by_ref(self: &Arc<Self>) {
        self.ready.push(self.id);
    }
}

/// The gateway's UDP sockets and their requests' tasks, run by the bus thread.
pub(crate) struct OnBus {
    shared: Arc<Shared>,
    sockets: Vec<Arc<UdpSocket>>,
    /// Readable while a socket has a datagram or a task was woken from another thread.
    epoll: OwnedFd,
    ready: Arc<Ready>,
    tasks: Vec<Option<Task>>,
    wakers: Vec<Waker>,
    free: Vec<usize>,
    buf: Box<[u8]>,
    runtime: tokio::runtime::Handle,
    /// Dropped with the guest: tells the gateway's stop that the socket is given up.
    _gone: std::sync::mpsc::Sender<()>,
}

impl OnBus {
    /// A guest for `sockets` (non-blocking), whose tasks' timers and spawns go to
    /// `runtime`; and what disconnects when the guest is dropped.
    pub fn new(
        shared: Arc<Shared>,
        sockets: Vec<UdpSocket>,
        runtime: tokio::runtime::Handle,
    ) -> io::Result<(OnBus, std::sync::mpsc::Receiver<()>)> {
        let epoll = epoll_create()?;
        let eventfd = EventFd::new()?;
        for fd in sockets
            .iter()
            .map(AsRawFd::as_raw_fd)
            .chain([eventfd.as_fd().as_raw_fd()])
        {
            epoll_add(&epoll, fd)?;
        }
        let (gone, gone_seen) = std::sync::mpsc::channel();
        let guest = OnBus {
            shared,
            sockets: sockets.into_iter().map(Arc::new).collect(),
            epoll,
            ready: Arc::new(Ready {
                ids: Mutex::default(),
                any: AtomicBool::new(false),
                eventfd,
            }),
            tasks: Vec::new(),
            wakers: Vec::new(),
            free: Vec::new(),
            buf: vec![0; RECEIVE_BUFFER].into_boxed_slice(),
            runtime,
            _gone: gone,
        };
        Ok((guest, gone_seen))
    }

    fn spawn(&mut self, task: Task) {
        let id = match self.free.pop() {
            Some(id) => {
                self.tasks[id] = Some(task);
                id
            }
            None => {
                let id = self.tasks.len();
                self.tasks.push(Some(task));
                self.wakers.push(Waker::from(Arc::new(TaskWaker {
                    id,
                    ready: Arc::clone(&self.ready),
                })));
                id
            }
        };
        self.ready.push(id);
    }

    fn poll(&mut self, id: usize) {
        let Some(task) = self.tasks.get_mut(id).and_then(Option::as_mut) else {
            // Woken after it ended (its slot free, or another task's now: a spurious poll
            // of that one is harmless).
            return;
        };
        let mut cx = Context::from_waker(&self.wakers[id]);
        // A task that panics ends alone, as on a worker's runtime: the bus thread goes on.
        let polled = std::panic::catch_unwind(AssertUnwindSafe(|| task.as_mut().poll(&mut cx)));
        if !matches!(polled, Ok(Poll::Pending)) {
            if polled.is_err() {
                tracing::error!("a mailbox gateway request panicked on the bus thread");
            }
            self.tasks[id] = None;
            self.free.push(id);
        }
    }

    /// Reads what `socket` has, up to the turn's share; whether it may have more.
    fn receive(&mut self, n: usize) -> bool {
        for _ in 0..RECEIVE_PER_TURN {
            let (len, client) = match self.sockets[n].recv_from(&mut self.buf) {
                Ok(received) => received,
                Err(err) if err.kind() == io::ErrorKind::WouldBlock => return false,
                // ICMP port unreachable from an earlier reply, and the like: not fatal.
                Err(_) => continue,
            };
            let Some((datagram, received)) = screened(&self.shared, &self.buf, len, client) else {
                continue;
            };
            let datagram = datagram.to_vec();
            let shared = Arc::clone(&self.shared);
            let socket = Arc::clone(&self.sockets[n]);
            self.spawn(Box::pin(async move {
                let reply_to = ReplyTo::UdpStd(socket);
                if let Admitted::Serve(request, ticket) =
                    admit(&shared, &datagram, client, reply_to, received).await
                {
                    drop(datagram);
                    serve(shared, request, ticket).await;
                }
            }));
        }
        true
    }
}

impl Guest for OnBus {
    fn wait_fd(&self) -> BorrowedFd<'_> {
        self.epoll.as_fd()
    }

    fn has_work(&self) -> bool {
        !self.ready.is_empty()
    }

    fn turn(&mut self, readable: bool, until: Option<StdInstant>) {
        let serving = Arc::as_ptr(&self.ready).addr();
        SERVING.with(|on| on.set(serving));
        let _runtime = self.runtime.enter();
        let mut more = false;
        if readable {
            self.ready.eventfd.drain();
            // New tasks only while the woken ones can be polled this turn: under a flood the
            // datagrams wait in the socket, whose buffer the kernel bounds (and counts what
            // it drops), not in this queue.
            if self.ready.len() < POLLS_PER_TURN {
                for n in 0..self.sockets.len() {
                    more |= self.receive(n);
                }
            } else {
                more = true;
            }
        }
        for polled in 0..POLLS_PER_TURN {
            // The cycle's frame goes first: checked every few polls (a poll is a few µs).
            if polled % 8 == 7 && until.is_some_and(|until| StdInstant::now() >= until) {
                break;
            }
            let Some(id) = self.ready.pop() else { break };
            self.poll(id);
        }
        if more || !self.ready.is_empty() {
            // Left for the next turn: the bus must not sleep meanwhile.
            self.ready.eventfd.signal();
        }
    }
}

fn epoll_create() -> io::Result<OwnedFd> {
    // SAFETY: no pointers; a non-negative result is a new descriptor we own.
    let fd = unsafe { libc::epoll_create1(libc::EPOLL_CLOEXEC) };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: as above.
    Ok(unsafe { OwnedFd::from_raw_fd(fd) })
}

fn epoll_add(epoll: &OwnedFd, fd: i32) -> io::Result<()> {
    // Level-triggered: readable while anything is left, so nothing is missed between turns.
    let mut event = libc::epoll_event {
        events: libc::EPOLLIN as u32,
        u64: 0,
    };
    // SAFETY: `event` is a live epoll_event for the call; both descriptors are open.
    let result = unsafe { libc::epoll_ctl(epoll.as_raw_fd(), libc::EPOLL_CTL_ADD, fd, &mut event) };
    if result < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}
