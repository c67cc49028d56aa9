//! ecatd's servers in a control program's own process: the program makes and owns the
//! [`Master`] (and its bus), runs its own cycle code, and hands the master to [`serve`] to
//! get everything ecatd serves over it: gRPC, REST with the dashboard and the metrics, the
//! ETG.8200 mailbox gateway, EoE interfaces, the application interface, readiness, and on
//! shutdown every slave in the safe state. It is the code `ecatd` itself runs once its
//! segment is open ([`crate::daemon`]), without what belongs to a process: signals, SIGHUP,
//! systemd, logging and the runtime stay the program's.
//!
//! ```no_run
//! # async fn program(master: std::sync::Arc<master_core::master::Master>) -> Result<(), String> {
//! use server::config::Config;
//! use server::embed::Embedded;
//!
//! let mut config = Config::default();
//! // The program installs its own cycle hook: the application interface would replace it.
//! config.app.enabled = false;
//! // Scanned by the program already; serve until Ctrl-C.
//! Embedded::new(master, config)
//!     .scanned()
//!     .serve(async {
//!         let _ = tokio::signal::ctrl_c().await;
//!     })
//!     .await
//! # }
//! ```
//!
//! `server/examples/embedded.rs` is a whole program: the simulated segment, a cycle hook that
//! mirrors inputs to outputs, and the servers (docs/application.md, "Embedding").
//!
//! # The configuration
//!
//! [`Config`] is ecatd's; these parts apply: `grpc_listen`, `http_listen`, `gateway`,
//! `tokens`, `tls`, `insecure`, `allowed_hosts`, `metrics_token`, `limits`, `watch`, `eoe`,
//! `capture` (the rolling capture needs [`Embedded::capture`]), `app`, `safe_state` and
//! `shutdown_timeout_ms`. `segment`, if given, only names the link the program's master runs
//! on (for the metrics' `ecat_link_up`, the EoE interfaces' MAC addresses and the link name
//! the APIs show); it is never opened. The master's own settings (`[bus]`, `[[slave]]`,
//! `[[group]]`, `eni`) are the program's to apply when it makes the master
//! ([`Config::segment_setup`] gives them as ecatd would apply them); the log settings and
//! `api_threads` are the program's too (`server::logging::init`, its tokio runtime).
//!
//! # Cycle hooks
//!
//! The master runs one [`CycleHook`](master_core::master::CycleHook) at a time
//! ([`Master::set_cycle_hook`]). The application interface (`[app]`, on by default) installs
//! its own when it starts, after the scan, and would replace the program's; and while a
//! program in another process owns the outputs through it, nothing else may write them. A
//! program with a cycle hook of its own therefore sets `config.app.enabled = false`.

use std::future::Future;
use std::sync::Arc;

use master_core::link::CaptureHub;
use master_core::master::Master;

use crate::config::Config;
use crate::daemon::{Host, Listeners, Served};
use crate::sim_hooks::SimHooks;

/// ecatd's servers over a master the program owns; [`Embedded::serve`] runs them.
pub struct Embedded {
    master: Arc<Master>,
    config: Config,
    scan: bool,
    sim: Option<SimHooks>,
    capture: Option<Arc<CaptureHub>>,
}

impl Embedded {
    /// The servers of `config` over `master`. By default [`Embedded::serve`] scans the
    /// segment first, as ecatd does at start.
    pub fn new(master: Arc<Master>, config: Config) -> Embedded {
        Embedded {
            master,
            config,
            scan: true,
            sim: None,
            capture: None,
        }
    }

    /// The program has scanned the master already (to look its entries up before the
    /// servers run, say): [`Embedded::serve`] does not scan again. The metrics then count
    /// configuration findings from later scans only.
    pub fn scanned(mut self) -> Embedded {
        self.scan = false;
        self
    }

    /// The capture hub of a [`CaptureTap`](master_core::link::CaptureTap) around the
    /// program's link, for `ecat pcap` and the rolling capture (`[capture] rolling`, which
    /// is refused without one).
    pub fn capture(mut self, hub: Arc<CaptureHub>) -> Embedded {
        self.capture = Some(hub);
        self
    }

    /// The hooks into an in-process simulator (`SimHooks::new` over the handles of
    /// `sim::topology::build_with_handles`), for the simulator's debug routes as `ecatd
    /// --simulate` serves them.
    pub fn sim_hooks(mut self, hooks: SimHooks) -> Embedded {
        self.sim = Some(hooks);
        self
    }

    /// Binds the listeners, scans (unless [`Embedded::scanned`]), serves until `shutdown`
    /// completes, then stops the servers and brings every slave to `safe_state` within
    /// `shutdown_timeout_ms`. The master and its bus keep running afterwards: stopping them
    /// is the program's. Errors are start-up failures (a bad configuration, a taken port, a
    /// configuration that does not fit the segment), before anything is served or after
    /// the servers stopped again.
    ///
    /// Runs on the caller's tokio runtime, which needs its I/O and time drivers
    /// (`enable_all`); ecatd's own is multi-threaded with `api_threads` workers. The
    /// returned future is `Send` when `shutdown` is, so it may run as a task of its own.
    pub async fn serve(self, shutdown: impl Future<Output = ()>) -> Result<(), String> {
        let Embedded {
            master,
            config,
            scan,
            sim,
            capture,
        } = self;
        // ecatd checks these when it reads the configuration and opens its segment; here
        // the configuration may come from anywhere.
        config.check()?;
        config.eoe.check()?;
        config.app.check()?;
        config.capture.check()?;
        let listeners = Listeners::bind(&config).await?;
        let served = Served {
            master,
            sim,
            capture,
            scan,
        };
        let shutdown = async {
            shutdown.await;
            "requested"
        };
        let result =
            crate::daemon::serve(&config, listeners, served, Host::Program, shutdown).await;
        if result.is_ok() {
            tracing::info!("stopped");
        }
        result.map_err(|failure| failure.to_string())
    }
}

/// [`Embedded::new`]`(master, config).`[`serve`](Embedded::serve)`(shutdown)`: scans, serves
/// until `shutdown` completes, brings the slaves to the safe state.
pub async fn serve(
    master: Arc<Master>,
    config: Config,
    shutdown: impl Future<Output = ()>,
) -> Result<(), String> {
    Embedded::new(master, config).serve(shutdown).await
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A program may run the servers as a task of its own (`tokio::spawn`).
    #[test]
    fn serving_is_a_send_future() {
        fn send<T: Send>(_: &T) {}
        // Checked by the compiler; the closure is never called.
        let check = |master: Arc<Master>| {
            send(&serve(master, Config::default(), std::future::pending()));
        };
        let _ = check;
    }
}
