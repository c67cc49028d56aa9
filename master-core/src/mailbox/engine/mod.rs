//! The engine: each slave's mailbox behind a fair lock, taken in turns by the requests
//! (in their callers' futures) and by the slave's owner task, which runs on the
//! engine's own thread (a current-thread tokio runtime) and sends the side traffic and
//! reads what the slave sends on its own.
//!
//! - [`slave`]: the public per-slave handle and what it shares with the owner;
//! - [`turn`]: one piece of work at the mailbox, and the lock that orders them;
//! - [`job`]: a request's trip from a caller to the mailbox and back (cancellation included);
//! - [`owner`]: the owner task's loop (EoE, then idle reads);
//! - [`exchange`]: writing SM0, reading SM1, routing what was read;
//! - [`counter`], [`repeat`]: the guards against retried writes and lost reads;
//! - [`answer_time`]: when a slow slave's answer is due, learned from its last answers;
//! - [`demux`]: where each message from a slave goes;
//! - [`hook`]: how the side traffic (EoE) plugs in, without the engine knowing it;
//! - [`events`], [`stats`]: unsolicited messages and counters;
//! - [`report`]: log lines for failures, rate-limited per slave;
//! - [`timer`]: the sub-millisecond pauses of the poll back-off.

pub(crate) mod answer_time;
pub(crate) mod counter;
pub(crate) mod demux;
pub(crate) mod events;
pub(crate) mod exchange;
pub(crate) mod hook;
pub(crate) mod job;
pub(crate) mod owner;
pub(crate) mod repeat;
pub(crate) mod report;
pub(crate) mod slave;
pub(crate) mod stats;
pub(crate) mod timer;
pub(crate) mod turn;

use std::collections::HashMap;
use std::io;
use std::sync::atomic::{AtomicU8, AtomicUsize};
use std::sync::{Arc, PoisonError, RwLock};
use std::thread::JoinHandle;

use tokio::sync::{Notify, watch};

use crate::bus::BusHandle;

use super::config::{MailboxConfig, SlaveMailboxConfig};
use super::error::{MailboxError, Result};
use events::Events;
use exchange::Exchange;
use slave::{SlaveMailbox, SlaveShared};
use turn::Mailbox;

/// The mailbox engine of a master: owns the mailbox of every slave added to it.
///
/// Cheap to clone. The engine stops when [`MailboxEngine::shutdown`] is called or the last
/// clone is dropped; requests then fail with [`MailboxError::Shutdown`].
///
/// ```no_run
/// # async fn demo(engine: master_core::mailbox::MailboxEngine) -> master_core::mailbox::Result<()> {
/// let drive = engine.slave(0x1001)?;
/// let identity = drive.sdo_upload(0x1018, 1).await?;
/// drive.sdo_download(0x6040, 0, &0x000Fu16.to_le_bytes()).await?;
/// # let _ = identity;
/// # Ok(())
/// # }
/// ```
#[derive(Clone)]
pub struct MailboxEngine {
    inner: Arc<Inner>,
}

struct Inner {
    bus: BusHandle,
    config: MailboxConfig,
    runtime: tokio::runtime::Handle,
    slaves: RwLock<HashMap<u16, Entry>>,
    stop: watch::Sender<bool>,
    thread: std::sync::Mutex<Option<JoinHandle<()>>>,
    timer: timer::Timer,
    /// Stops the pause thread with the engine.
    _timer_thread: timer::TimerThread,
}

/// A slave the engine owns: what its handles share, and its mailbox.
struct Entry {
    shared: Arc<SlaveShared>,
    mailbox: Mailbox,
}

impl Drop for Inner {
    fn drop(&mut self) {
        self.stop.send_replace(true);
    }
}

impl std::fmt::Debug for MailboxEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MailboxEngine")
            .field("config", &self.inner.config)
            .field("slaves", &self.stations())
            .finish()
    }
}

impl MailboxEngine {
    /// Starts the engine's thread (named `ecat-mailbox`) on `bus`, without slaves.
    ///
    /// Fails if the runtime or the thread cannot be created.
    pub fn start(bus: BusHandle, config: MailboxConfig) -> io::Result<MailboxEngine> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()?;
        let handle = runtime.handle().clone();
        let (timer, timer_thread) = timer::Timer::start()?;
        let (stop, mut stopped) = watch::channel(false);
        let thread = std::thread::Builder::new()
            .name("ecat-mailbox".into())
            .spawn(move || {
                runtime.block_on(async move {
                    // Ends on shutdown, or when the engine is dropped (sender gone).
                    while !*stopped.borrow_and_update() {
                        if stopped.changed().await.is_err() {
                            break;
                        }
                    }
                });
            })?;
        Ok(MailboxEngine {
            inner: Arc::new(Inner {
                bus,
                config,
                runtime: handle,
                slaves: RwLock::new(HashMap::new()),
                stop,
                thread: std::sync::Mutex::new(Some(thread)),
                timer,
                _timer_thread: timer_thread,
            }),
        })
    }

    /// Takes over the mailbox of a slave (its owner task starts at once) and returns its
    /// handle. A slave already known under the same station address is replaced: its
    /// owner stops and its queued requests fail with [`MailboxError::Shutdown`]; the new
    /// owner continues its request counters, since the slave still remembers the last one
    /// (a slave that went through INIT starts afresh: [`MailboxEngine::remove_slave`] it
    /// first, as the master does when a slave falls back to INIT).
    pub fn add_slave(&self, config: SlaveMailboxConfig) -> SlaveMailbox {
        let last_tx = self
            .inner
            .slaves
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&config.station)
            .map_or(0, |old| {
                old.shared
                    .last_tx
                    .load(std::sync::atomic::Ordering::Relaxed)
            });
        let engine = self.inner.config;
        let side = super::side_traffic(&engine);
        let (stop, stop_rx) = watch::channel(false);
        let shared = Arc::new(SlaveShared {
            config,
            engine,
            waiting: AtomicUsize::new(0),
            run: std::sync::Mutex::new(None),
            runtime: self.inner.runtime.clone(),
            engine_stop: self.inner.stop.subscribe(),
            side_queue: side.queue,
            events: Events::new(engine.emergency_history, engine.event_capacity),
            stats: stats::Stats::default(),
            mail: Notify::new(),
            answer: Notify::new(),
            stop,
            last_tx: AtomicU8::new(last_tx),
            log_limit: report::LogLimit::default(),
            timer: self.inner.timer.clone(),
        });
        let exchange = Exchange::new(Arc::clone(&shared), self.inner.bus.clone(), side.reassembly);
        let mailbox: Mailbox = Arc::new(tokio::sync::Mutex::new(exchange));
        let inputs = owner::Inputs {
            mailbox: Arc::clone(&mailbox),
            background: side.background,
            stop: stop_rx,
            engine_stop: self.inner.stop.subscribe(),
        };
        self.inner
            .runtime
            .spawn(owner::run(Arc::clone(&shared), inputs));
        let entry = Entry {
            shared: Arc::clone(&shared),
            mailbox: Arc::clone(&mailbox),
        };
        let replaced = self
            .inner
            .slaves
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(config.station, entry);
        if let Some(old) = replaced {
            old.shared.stop.send_replace(true);
        }
        SlaveMailbox::new(shared, mailbox)
    }

    /// Stops owning the mailbox of slave `station` (it left the segment); its queued
    /// requests fail with [`MailboxError::Shutdown`]. Returns whether it was known.
    pub fn remove_slave(&self, station: u16) -> bool {
        let removed = self
            .inner
            .slaves
            .write()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(&station);
        if let Some(entry) = &removed {
            entry.shared.stop.send_replace(true);
        }
        removed.is_some()
    }

    /// The handle of slave `station`.
    pub fn slave(&self, station: u16) -> Result<SlaveMailbox> {
        self.inner
            .slaves
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&station)
            .map(|entry| SlaveMailbox::new(Arc::clone(&entry.shared), Arc::clone(&entry.mailbox)))
            .ok_or(MailboxError::UnknownSlave(station))
    }

    /// The station addresses of the slaves the engine owns, ascending.
    pub fn stations(&self) -> Vec<u16> {
        let mut stations: Vec<u16> = self
            .inner
            .slaves
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .keys()
            .copied()
            .collect();
        stations.sort_unstable();
        stations
    }

    /// Reads slave `station`'s send mailbox now: the hook for the process-data path, which
    /// sees the "mailbox full" bit of SM1 in the cyclic frame (spec-notes §mbx.handshake) and can replace
    /// polling ([`MailboxConfig::idle_poll`] `None`). Unknown stations are ignored.
    pub fn notify_mailbox_full(&self, station: u16) {
        if let Ok(slave) = self.slave(station) {
            slave.notify_mailbox_full();
        }
    }

    /// The engine's settings.
    pub fn config(&self) -> &MailboxConfig {
        &self.inner.config
    }

    /// Stops the engine and waits for its thread. Requests under way or queued fail with
    /// [`MailboxError::Shutdown`] (a message already written may have been carried out).
    pub fn shutdown(&self) {
        self.inner.stop.send_replace(true);
        let thread = self
            .inner
            .thread
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some(thread) = thread
            && thread.thread().id() != std::thread::current().id()
        {
            let _ = thread.join();
        }
    }
}
