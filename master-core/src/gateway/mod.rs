//! The ETG.8200 mailbox gateway (spec-notes §gateway, docs/gateway.md): configuration and diagnosis
//! tools send raw mailbox messages over UDP, the gateway relays them to the slaves'
//! mailboxes (or to the master's own dictionary at address 0) and sends the answers back.
//!
//! ```no_run
//! # use std::sync::Arc;
//! # use master_core::gateway::{GatewayConfig, MailboxGateway};
//! # fn demo(master: Arc<master_core::master::Master>) -> std::io::Result<()> {
//! let mut gateway = MailboxGateway::new(master, GatewayConfig::default());
//! gateway.start()?;
//! println!("mailbox gateway on port {}", gateway.port());
//! let stats = gateway.stats();
//! println!("{} requests, {} failed", stats.total_requests, stats.failed_requests);
//! gateway.stop();
//! # Ok(()) }
//! ```
//!
//! The service runs beside the bus and the master and reaches the slaves only through the
//! mailbox engine, whose per-slave queues it shares with every other user: the cyclic
//! exchange is never touched. Where the bus can wait on its link with a descriptor,
//! [`GatewayConfig::on_bus_thread`] (the default) has the bus thread itself serve the UDP
//! socket between its frames (`on_bus`): a request then wakes no thread but the bus's.
//! Otherwise, and for TCP, the dictionary's tracker and the requests' timers in either case,
//! it runs on its own threads (`ecat-gateway-N`, [`GatewayConfig::workers`] of them, each a
//! current-thread runtime with its own UDP socket on the shared port; the first also serves
//! TCP). The kernel gives each client to one worker (`bind`), so a client's requests are
//! taken in the order sent; sessions, caps and the stored replies of repeats are shared by
//! every worker.
//!
//! Files: `config`, `allow` (client networks), `bind` (port and fallback), `service` (the
//! transport-neutral request handling), `udp` (the datagram loop), `on_bus` (the same on
//! the bus thread), `route` (addresses),
//! `forward` (one slave), `transfer` (what a message makes the slave do and the
//! multi-message transfer it leaves open), `session` (slaves held for a transfer), `normalize`
//! (tolerated short SDO requests), `compat` (the layout of the replaced gateway's manual clients),
//! `answer` (the gateway's own error answers), `reply` (datagrams back), `retry` (repeated
//! requests answered once), `access` (which requests write: roles), `audit` (audit lines of
//! writes), `admission` (in-flight caps), `stats`, `tcp` (the optional TCP transport over
//! the same service), `fuzzing` (the parsing steps for the fuzz target).

mod access;
mod admission;
mod allow;
mod answer;
mod ask;
mod audit;
mod bind;
mod compat;
mod config;
mod forward;
#[doc(hidden)]
pub mod fuzzing;
mod kernel_drops;
mod normalize;
mod on_bus;
mod reply;
mod retry;
mod route;
mod service;
mod session;
mod stats;
mod tcp;
mod transfer;
mod udp;

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;
use std::thread::JoinHandle;

use tokio::sync::watch;

use crate::master::Master;
use crate::master_od::MasterDictionary;

pub use allow::{AllowedNet, ClientNet, ClientNetError, GatewayRole};
pub use config::{
    DEFAULT_PORT, GatewayConfig, MAX_DEFAULT_WORKERS, default_workers, port_for_master,
};
pub use kernel_drops::udp_drops;
pub use route::{BROADCAST_ADDRESS, MASTER_ADDRESS, POSITION_BASE};
pub use stats::{FailureCounts, FailureReason, MailboxGatewayStats};

use admission::Admission;
use service::Shared;
use session::Sessions;
use stats::Stats;

/// A running service: its address, how to stop it, its worker threads.
struct Running {
    local: SocketAddr,
    /// The UDP sockets' inodes ([`kernel_drops`]).
    inodes: Vec<u64>,
    stop: watch::Sender<bool>,
    threads: Vec<JoinHandle<()>>,
    /// Disconnected once the bus thread has dropped the guest serving UDP (`on_bus`).
    /// (In a mutex only to make the gateway `Sync`.)
    guest_gone: Option<std::sync::Mutex<std::sync::mpsc::Receiver<()>>>,
}

/// How long a stop waits for the bus thread to give the socket up: it looks at its control
/// requests at least every millisecond, so only a bus that is gone takes this long.
const GUEST_GONE_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

impl Running {
    /// Stops serving: the bus thread's guest first (its tasks use the first worker's
    /// runtime, which must outlive them), then the workers.
    fn end(&mut self, master: &Master) {
        if let Some(gone) = self.guest_gone.take() {
            let _ = master.bus().set_guest(None);
            let gone = gone
                .into_inner()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            let _ = gone.recv_timeout(GUEST_GONE_WAIT);
        }
        let _ = self.stop.send(true);
        for thread in self.threads.drain(..) {
            let _ = thread.join();
        }
    }
}

/// The ETG.8200 mailbox gateway of one master. See the [module documentation](self).
///
/// Dropping it stops the service.
pub struct MailboxGateway {
    master: Arc<Master>,
    config: GatewayConfig,
    stats: Arc<Stats>,
    running: Option<Running>,
}

impl std::fmt::Debug for MailboxGateway {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MailboxGateway")
            .field("config", &self.config)
            .field("local", &self.local_addr())
            .finish()
    }
}

impl MailboxGateway {
    /// A gateway for `master`, not started.
    pub fn new(master: Arc<Master>, config: GatewayConfig) -> MailboxGateway {
        MailboxGateway {
            master,
            config,
            stats: Arc::default(),
            running: None,
        }
    }

    /// The settings (changes made with [`Self::config_mut`] apply at the next start).
    pub fn config(&self) -> &GatewayConfig {
        &self.config
    }

    /// The settings, to change before a start.
    pub fn config_mut(&mut self) -> &mut GatewayConfig {
        &mut self.config
    }

    /// The port: the one bound while running (after a fallback, the fallback port), else
    /// the one the next start asks for.
    pub fn port(&self) -> u16 {
        self.running
            .as_ref()
            .map_or_else(|| self.config.wanted_port(), |r| r.local.port())
    }

    /// Sets the port the next start asks for (0: any free port).
    pub fn set_port(&mut self, port: u16) {
        self.config.port = Some(port);
    }

    /// The address bound, while running (with [`GatewayConfig::tcp`], TCP listens on the
    /// same address and port).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.running.as_ref().map(|r| r.local)
    }

    /// Whether the bus thread serves the UDP socket ([`GatewayConfig::on_bus_thread`],
    /// where the bus can), while running.
    pub fn on_bus_thread(&self) -> bool {
        self.running
            .as_ref()
            .is_some_and(|r| r.guest_gone.is_some())
    }

    /// Whether the service is running.
    pub fn is_running(&self) -> bool {
        self.running
            .as_ref()
            .is_some_and(|r| !r.threads.is_empty() && r.threads.iter().all(|t| !t.is_finished()))
    }

    /// The inodes of the UDP sockets while running, for [`udp_drops`]: the datagrams the
    /// kernel dropped before the gateway could read them (none when not running).
    pub fn socket_inodes(&self) -> Vec<u64> {
        self.running
            .as_ref()
            .map_or_else(Vec::new, |r| r.inodes.clone())
    }

    /// Statistics since the last start (lock-free; any thread, any time).
    pub fn stats(&self) -> MailboxGatewayStats {
        self.stats.snapshot()
    }

    /// Binds the socket and starts serving; returns the address bound. If the wanted port
    /// is taken and [`GatewayConfig::fallback`] is set, a free port is bound instead (see
    /// [`Self::port`]). Starting a running gateway returns its address. Counters start
    /// from zero.
    pub fn start(&mut self) -> io::Result<SocketAddr> {
        if let Some(local) = self.local_addr()
            && self.is_running()
        {
            return Ok(local);
        }
        self.stop();
        // Served by the bus thread: one socket, waited on beside the link; one worker is
        // left for TCP, the dictionary's tracker, the timers and what the requests spawn.
        let on_bus = self.config.on_bus_thread && self.master.bus().can_host_guest();
        let bound = bind::bind(
            self.config.bind,
            self.config.wanted_port(),
            self.config.fallback,
            self.config.tcp,
            if on_bus { 1 } else { self.config.workers },
        )?;
        let fell_back = bound.fell_back;
        let mut runtimes = Vec::with_capacity(bound.udp.len());
        let mut inodes = Vec::with_capacity(bound.udp.len());
        let mut bus_sockets = Vec::new();
        for udp in bound.udp {
            inodes.push(kernel_drops::socket_inode(&udp)?);
            udp.set_nonblocking(true)?;
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()?;
            let local = udp.local_addr()?;
            if on_bus {
                // Not the runtime's: its readiness would wake the worker for nothing.
                bus_sockets.push(udp);
                runtimes.push((runtime, None, local));
                continue;
            }
            let socket = {
                let _inside = runtime.enter();
                tokio::net::UdpSocket::from_std(udp)?
            };
            runtimes.push((runtime, Some(socket), local));
        }
        let local = runtimes[0].2;
        let listener = match bound.tcp {
            Some(listener) => {
                listener.set_nonblocking(true)?;
                let _inside = runtimes[0].0.enter();
                Some(tokio::net::TcpListener::from_std(listener)?)
            }
            None => None,
        };
        if fell_back {
            eprintln!(
                "ecat-gateway: port {} is taken, serving on {}",
                self.config.wanted_port(),
                local.port()
            );
        }
        self.stats.start(local.port());
        let shared = Arc::new(Shared {
            dictionary: MasterDictionary::new(
                Arc::clone(&self.master),
                self.config.identity.clone(),
                usize::from(self.config.master_mailbox_size),
            ),
            master: Arc::clone(&self.master),
            config: self.config.clone(),
            stats: Arc::clone(&self.stats),
            sessions: Sessions::default(),
            admission: Arc::new(Admission::new(
                self.config.max_in_flight,
                self.config.max_in_flight_per_client,
                Arc::clone(&self.stats),
            )),
            retries: retry::Retries::new(self.config.retry_window, self.config.max_retry_clients),
            log_backlog: audit::Backlog::default(),
        });
        let guest = if bus_sockets.is_empty() {
            None
        } else {
            Some(on_bus::OnBus::new(
                Arc::clone(&shared),
                bus_sockets,
                runtimes[0].0.handle().clone(),
            )?)
        };
        let (stop, stopped) = watch::channel(false);
        let mut listener = listener;
        let mut threads = Vec::with_capacity(runtimes.len());
        for (n, (runtime, socket, _)) in runtimes.into_iter().enumerate() {
            let (shared, stopped) = (Arc::clone(&shared), stopped.clone());
            // The first worker also keeps the dictionary's counters and serves TCP.
            let first = n == 0;
            let listener = listener.take();
            let spawned = std::thread::Builder::new()
                .name(format!("ecat-gateway-{n}"))
                .spawn(move || {
                    runtime.block_on(run(shared, socket, listener, first, stopped));
                    // Dropping the runtime drops the request tasks still running, which
                    // cancels their mailbox requests.
                });
            match spawned {
                Ok(thread) => threads.push(thread),
                Err(err) => {
                    let _ = stop.send(true);
                    for thread in threads {
                        let _ = thread.join();
                    }
                    self.stats.stop();
                    return Err(err);
                }
            }
        }
        let mut running = Running {
            local,
            inodes,
            stop,
            threads,
            guest_gone: None,
        };
        if let Some((guest, gone)) = guest {
            if self.master.bus().set_guest(Some(Box::new(guest))).is_err() {
                running.end(&self.master);
                self.stats.stop();
                return Err(io::Error::other(
                    "the bus cannot serve the gateway's socket",
                ));
            }
            running.guest_gone = Some(std::sync::Mutex::new(gone));
        }
        self.running = Some(running);
        Ok(local)
    }

    /// Stops serving and releases the port (requests under way are cancelled). A stopped
    /// gateway can be started again.
    pub fn stop(&mut self) {
        if let Some(mut running) = self.running.take() {
            running.end(&self.master);
            self.stats.stop();
        }
    }
}

/// One worker: serves its UDP socket (and TCP, with a listener) until `stop` says so (or
/// its sender is gone); the request tasks and TCP connections go with the runtime. The
/// `first` worker runs the dictionary's tracker.
async fn run(
    shared: Arc<Shared>,
    socket: Option<tokio::net::UdpSocket>,
    listener: Option<tokio::net::TcpListener>,
    first: bool,
    mut stop: watch::Receiver<bool>,
) {
    let tracker = first.then(|| tokio::spawn(shared.dictionary.tracker()));
    let udp = async {
        match socket {
            Some(socket) => udp::run(Arc::clone(&shared), Arc::new(socket)).await,
            None => std::future::pending().await,
        }
    };
    let tcp = async {
        match listener {
            Some(listener) => tcp::run(Arc::clone(&shared), listener).await,
            None => std::future::pending().await,
        }
    };
    tokio::select! {
        _ = stop.changed() => {}
        () = udp => {}
        () = tcp => {}
    }
    if let Some(tracker) = tracker {
        tracker.abort();
    }
}

impl Drop for MailboxGateway {
    fn drop(&mut self) {
        self.stop();
    }
}
