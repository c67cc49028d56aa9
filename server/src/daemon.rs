//! Start-up and shutdown: open the segment, scan it, serve both APIs, and on SIGINT or
//! SIGTERM (also during the start-up scan) end the event streams, stop serving, bring every
//! slave to the safe state (INIT, or SAFEOP as configured) within the shutdown deadline and
//! close the link. A second signal exits at once.
//!
//! [`run`] is the daemon: the process's signals and the segment the configuration names.
//! Everything after the segment is open (the listeners, the core, the servers, the scan,
//! readiness, the shutdown) is one code path, `Listeners::bind` then `serve`, which
//! [`embed`](crate::embed) also runs over a master that a control program owns.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio::time::Instant;

use master_core::gateway::MailboxGateway;
use master_core::link::CaptureHub;
use master_core::master::Master;

use crate::config::{Config, GatewaySettings, Segment};
use crate::exit::Failure;
use crate::security::Tokens;
use crate::service::Core;
use crate::signals::Signals;
use crate::sim_hooks::SimHooks;
use crate::{grpc, http, segment};

/// Runs ecatd with `config` until a signal; errors are start-up failures.
pub async fn run(config: Config) -> Result<(), Failure> {
    config.check().map_err(Failure::configuration)?;
    config.eoe.check().map_err(Failure::configuration)?;
    crate::scheduling::warn_if_started_realtime();
    // Installed first: a signal at any point of the start-up leads to a clean shutdown.
    let mut signals = Signals::install()?;
    let segment_config = config.segment.clone().ok_or_else(|| {
        Failure::configuration("no segment: pass --simulate [TOPOLOGY] or --iface NAME")
    })?;
    // Bind first so a taken port fails fast, before the segment is touched.
    let listeners = Listeners::bind(&config).await?;
    let setup = config.segment_setup().map_err(Failure::configuration)?;
    if !config.eni_unused.is_empty() {
        tracing::info!(
            eni = %config.eni.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
            unused = %config.eni_unused.join(", "),
            "ENI elements ecatd does not use"
        );
    }
    let running = segment::open(&segment_config, &setup)?;
    let served = Served {
        master: Arc::clone(&running.master),
        sim: running.sim.clone(),
        capture: Some(Arc::clone(&running.capture)),
        scan: true,
    };
    let shutdown = async move {
        let signal = signals.next().await;
        // A second signal exits at once (the slaves' SyncManager watchdogs then take the
        // outputs to their safe state).
        signals.exit_on_next();
        signal
    };
    let result = serve(&config, listeners, served, Host::Daemon, shutdown).await;
    // The bus stops with the master: no cycle drives outputs after this.
    running.stop();
    if result.is_ok() {
        tracing::info!("stopped");
    }
    result
}

/// The sockets ecatd serves on and the TLS files, taken before the segment is touched so
/// that a taken port, socket or unreadable certificate fails the start at once.
pub(crate) struct Listeners {
    grpc: TcpListener,
    http: TcpListener,
    app: Option<(crate::app::AppListener, Vec<crate::app::SafeValue>)>,
    tls: Option<crate::tls::TlsFiles>,
}

impl Listeners {
    /// Binds gRPC, HTTP and the application interface's socket of `config` and loads its
    /// TLS files.
    pub(crate) async fn bind(config: &Config) -> Result<Listeners, String> {
        let grpc = bind(config.grpc_listen, "gRPC").await?;
        let http = bind(config.http_listen, "HTTP").await?;
        let app = bind_app(config)?;
        let tls = config
            .tls
            .as_ref()
            .map(crate::tls::TlsFiles::load)
            .transpose()?;
        Ok(Listeners {
            grpc,
            http,
            app,
            tls,
        })
    }
}

/// The segment [`serve`] runs over: its master and what came with it.
pub(crate) struct Served {
    /// The master; whoever opened the segment keeps its own handle (and stops the bus).
    pub(crate) master: Arc<Master>,
    /// The in-process simulator's hooks, for its debug routes.
    pub(crate) sim: Option<SimHooks>,
    /// The bus's frames, for `ecat pcap` and the rolling capture; `None`: no capture.
    pub(crate) capture: Option<Arc<CaptureHub>>,
    /// Whether to scan at start (false: the master is scanned already).
    pub(crate) scan: bool,
}

/// Whose process [`serve`] runs in: the daemon also does what belongs to the process
/// (SIGHUP, systemd's notifications, the bus thread's scheduling from `[bus]`); a program
/// that embeds the servers owns its process and its bus, and decides those itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Host {
    /// `ecatd`.
    Daemon,
    /// A control program ([`crate::embed`]).
    Program,
}

/// Serves everything over `served` until `shutdown` completes (its output names the cause
/// in the log), then brings the slaves to the safe state and returns; stopping the bus is
/// the caller's. Errors are start-up failures.
pub(crate) async fn serve(
    config: &Config,
    listeners: Listeners,
    served: Served,
    host: Host,
    shutdown: impl Future<Output = &'static str>,
) -> Result<(), Failure> {
    let Listeners {
        grpc: grpc_listener,
        http: http_listener,
        app: app_listener,
        tls,
    } = listeners;
    // Polled in the scan's race and again afterwards, to its end only once.
    tokio::pin!(shutdown);
    // What the metrics record lives beside the core; the core only records its requests.
    let metrics = Arc::new(crate::metrics::Store {
        link: match &config.segment {
            Some(Segment::Simulate { .. }) => crate::metrics::state::Link::Simulated,
            Some(Segment::Iface { name }) => crate::metrics::state::Link::Iface(name.clone()),
            None => crate::metrics::state::Link::Unknown,
        },
        ..Default::default()
    });
    let core = Core::new(served.master, Arc::clone(&metrics.calls));
    // The event history begins before the first scan, so that its events are kept.
    core.start_events(&config.events)
        .map_err(Failure::configuration)?;
    core.set_effective_config(
        config.to_toml(),
        config
            .eni
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_default(),
    );
    // Before the scan: its findings against the configuration are counted too.
    let findings = metrics.config.follow(core.master());
    if let Some(capture) = served.capture {
        core.set_capture(capture);
    }
    if config.capture.rolling {
        core.start_rolling(&config.capture)
            .map_err(|err| format!("rolling capture: {}", err.message))?;
        tracing::info!(
            dir = %config.capture.dir.display(),
            files = config.capture.files,
            file_kib = config.capture.file_kib,
            "rolling capture running"
        );
    }
    match &config.segment {
        Some(Segment::Simulate { .. }) => core.set_link("simulate"),
        Some(Segment::Iface { name }) => core.set_link(name),
        None => {}
    }
    let tokens = Tokens::new(config.tokens.clone());
    if host == Host::Daemon {
        reload_on_sighup(config, &tokens, tls.clone())?;
    }
    tracing::info!(
        grpc = %config.grpc_listen_of(&grpc_listener),
        http = %config.http_listen_of(&http_listener),
        tokens = tokens.enabled(),
        tls = tls.is_some(),
        // The runtime's own count (`api_threads`, or whatever runtime a caller gave).
        api_threads = tokio::runtime::Handle::current().metrics().num_workers(),
        "listening"
    );
    let (stop_tx, stop_rx) = watch::channel(false);
    let stopped = |mut rx: watch::Receiver<bool>| async move {
        let _ = rx.wait_for(|stop| *stop).await;
    };
    let grpc_task = tokio::spawn(grpc::serve_tls(
        core.clone(),
        tokens.clone(),
        grpc_listener,
        tls.as_ref().map(crate::tls::TlsFiles::grpc).transpose()?,
        config.limits.clone(),
        Arc::clone(&metrics.connections.grpc),
        stopped(stop_rx.clone()),
    ));
    let hosts = http::browser::AllowedHosts::new(
        config.http_listen_of(&http_listener),
        &config.allowed_hosts,
    );
    let app = http::router(
        core.clone(),
        tokens,
        Arc::clone(&metrics),
        served.sim,
        config.metrics_token,
    )
    .layer(axum::middleware::from_fn_with_state(
        hosts,
        http::browser::guard,
    ));
    let connections = Arc::clone(&metrics.connections.http);
    let http_task = match &tls {
        Some(files) => tokio::spawn(http::serve_tls(
            app,
            crate::tls::TlsListener::new(http_listener, files.http()?),
            config.limits.clone(),
            connections,
            stopped(stop_rx),
        )),
        None => tokio::spawn(http::serve(
            app,
            http_listener,
            config.limits.clone(),
            connections,
            stopped(stop_rx),
        )),
    };

    // A shutdown during the start-up scan stops the scan where it is.
    let signal = if !served.scan {
        None
    } else {
        tokio::select! {
            report = core.master().scan_cancellable() => {
                match report {
                    Ok(report) => {
                        for failure in &report.failures {
                            tracing::warn!(%failure, "slave did not reach its target state");
                        }
                        tracing::info!(slaves = report.slaves.len(), "segment scanned");
                    }
                    // The configuration does not fit the segment: found before any slave
                    // left INIT, so nothing of it was applied; ecatd does not start.
                    Err(err @ master_core::master::MasterError::Configuration { .. }) => {
                        tracing::error!(%err, "the configuration does not fit the segment");
                        core.stop_streams();
                        let _ = stop_tx.send(true);
                        let _ = grpc_task.await;
                        let _ = http_task.await;
                        findings.abort();
                        return Err(Failure::configuration(format!(
                            "the configuration does not fit the segment: {err}"
                        )));
                    }
                    Err(err) => {
                        tracing::error!(%err, "scan failed; the APIs stay up, retry with Rescan")
                    }
                }
                None
            }
            signal = &mut shutdown => Some(signal),
        }
    };
    let background = match signal {
        Some(_) => None,
        None => {
            core.master().start_watch(Duration::from_millis(100));
            let eoe = start_eoe(&core, config);
            let background = (crate::metrics::start(&core, &metrics, &config.watch), eoe);
            let app =
                app_listener.and_then(|(listener, safe)| start_app(&core, config, listener, safe));
            if let Some(settings) = &config.gateway
                && let Err(err) = start_gateway(&core, settings).await
            {
                tracing::error!(%err, "mailbox gateway not started");
                core.publish_event(crate::service::view::EventView::note(
                    "gateway_failed",
                    format!("mailbox gateway not started: {err}"),
                ));
            }
            if host == Host::Daemon {
                // The scan ran its frames through the bus thread: it has applied its
                // scheduling. (A program started its bus itself, not from `[bus]`.)
                crate::scheduling::warn_if_not_granted(
                    config.bus.rt_priority,
                    core.master().bus().stats().realtime,
                );
            }
            core.set_ready(true);
            tracing::info!("ready");
            let watchdog = (host == Host::Daemon)
                .then(|| {
                    crate::systemd::notify(sd_notify::NotifyState::Ready);
                    let master = Arc::clone(core.master());
                    crate::systemd::start_watchdog(move || {
                        let s = master.bus().stats();
                        s.frames_sent + s.link_errors + s.datagrams_failed + s.cycles_run
                    })
                })
                .flatten();
            Some((background, app, watchdog))
        }
    };
    let signal = match signal {
        Some(signal) => signal,
        None => shutdown.await,
    };
    if host == Host::Daemon {
        crate::systemd::notify(sd_notify::NotifyState::Stopping);
    }
    let deadline = Instant::now() + Duration::from_millis(config.shutdown_timeout_ms);
    tracing::info!(
        signal,
        safe_state = %config.safe_state.al_state(),
        timeout_ms = config.shutdown_timeout_ms,
        "shutting down"
    );
    core.stop_streams();
    let _ = stop_tx.send(true);
    // The servers finish the requests in flight, within a third of the budget; the rest is
    // for the slaves.
    let servers_by = Instant::now() + (deadline - Instant::now()) / 3;
    for (name, mut task) in [("gRPC", grpc_task), ("HTTP", http_task)] {
        match tokio::time::timeout_at(servers_by, &mut task).await {
            Ok(Ok(Ok(()))) => {}
            Ok(Ok(Err(err))) => tracing::error!(%err, "{name} server failed"),
            Ok(Err(err)) => tracing::error!(%err, "{name} server task failed"),
            Err(_) => {
                tracing::warn!("{name} server still busy at its shutdown deadline; stopped");
                task.abort();
            }
        }
    }
    if let Some(mut gateway) = core.take_gateway() {
        if gateway.is_running() {
            core.publish_event(crate::service::view::EventView::note(
                "gateway_stopped",
                "mailbox gateway stopped (ecatd shuts down)".into(),
            ));
        }
        // Stopping joins the gateway's thread: off the async workers.
        let _ = tokio::task::spawn_blocking(move || gateway.stop()).await;
    }
    let (background, app) = match background {
        Some((background, app, watchdog)) => {
            // systemd stops watching at STOPPING=1.
            if let Some(watchdog) = watchdog {
                watchdog.abort();
            }
            (Some(background), app)
        }
        None => (None, None),
    };
    if let Some(app) = app {
        // The owner's outputs go to their safe values before the slaves leave OP.
        app.stop().await;
    }
    drop(background);
    findings.abort();
    core.master().stop_watch();
    let state = config.safe_state.al_state();
    match core.master().all_to_safe(state, deadline).await {
        Ok(report) if report.confirmed => {
            tracing::info!(slaves = report.slaves, %state, "slaves in the safe state")
        }
        Ok(report) => tracing::warn!(
            slaves = report.slaves,
            %state,
            "slaves not all confirmed in the safe state by the deadline"
        ),
        Err(err) => tracing::warn!(%err, "cannot bring the slaves to the safe state"),
    }
    Ok(())
}

/// On SIGHUP, reads the configuration file's tokens again and swaps them in, and reads the
/// TLS certificate and key again (when TLS is on) for new connections; the bus, established
/// connections and everything else stay as they are. A file that does not pass the
/// start-up checks keeps what is in use, and the log says why.
fn reload_on_sighup(
    config: &Config,
    tokens: &Tokens,
    tls: Option<crate::tls::TlsFiles>,
) -> Result<(), String> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut hangup =
        signal(SignalKind::hangup()).map_err(|err| format!("cannot handle SIGHUP: {err}"))?;
    let config = config.clone();
    let tokens = tokens.clone();
    tokio::spawn(async move {
        while hangup.recv().await.is_some() {
            if let Some(tls) = &tls {
                // Reading files: off the async workers.
                let tls = tls.clone();
                match tokio::task::spawn_blocking(move || tls.reload()).await {
                    Ok(Ok(())) => tracing::info!("SIGHUP: TLS certificate reloaded"),
                    Ok(Err(err)) => {
                        tracing::error!(%err, "SIGHUP: TLS certificate not reloaded; the previous one stays")
                    }
                    Err(err) => {
                        tracing::error!(%err, "SIGHUP: TLS certificate not reloaded; the previous one stays")
                    }
                }
            }
            let Some(file) = &config.file else {
                if tls.is_none() {
                    tracing::warn!("SIGHUP: no configuration file to reload the tokens from");
                }
                continue;
            };
            let (reload, path) = (config.clone(), file.clone());
            match tokio::task::spawn_blocking(move || reload.reload_tokens(&path)).await {
                Ok(Ok(set)) => {
                    let count = set.len();
                    tokens.replace(set);
                    tracing::info!(tokens = count, "SIGHUP: tokens reloaded");
                }
                Ok(Err(err)) => {
                    tracing::error!(%err, "SIGHUP: tokens not reloaded; the previous ones stay")
                }
                Err(err) => {
                    tracing::error!(%err, "SIGHUP: tokens not reloaded; the previous ones stay")
                }
            }
        }
    });
    Ok(())
}

/// Starts the EoE interface manager (none when `[eoe] enabled = false`).
fn start_eoe(core: &Core, config: &Config) -> Option<crate::eoe::EoeManager> {
    if !config.eoe.enabled {
        return None;
    }
    // The interfaces' MAC addresses are made from the NIC's; without one (simulator, or a
    // program that did not say), from the bus's source address.
    let nic = match &config.segment {
        Some(Segment::Iface { name }) => crate::eoe::tap::mac_of(name),
        Some(Segment::Simulate { .. }) | None => None,
    }
    .unwrap_or(master_core::bus::BusConfig::default().source_mac);
    match crate::eoe::start(
        Arc::clone(core.master()),
        &config.eoe,
        nic,
        core.eoe().clone(),
    ) {
        Ok(manager) => Some(manager),
        Err(err) => {
            tracing::error!(%err, "EoE interfaces not started");
            None
        }
    }
}

/// Binds the application interface's socket (before the segment is touched, so a taken
/// socket fails fast) and resolves the configured safe outputs' slaves.
fn bind_app(
    config: &Config,
) -> Result<Option<(crate::app::AppListener, Vec<crate::app::SafeValue>)>, String> {
    if !config.app.enabled {
        return Ok(None);
    }
    let mut safe = Vec::new();
    for value in &config.app.safe_output {
        let address = crate::input::address::parse_slave(&value.slave).map_err(|err| {
            format!(
                "[[app.safe_output]] slave {:?}: {}",
                value.slave, err.message
            )
        })?;
        safe.push(crate::app::SafeValue {
            address,
            index: value.index,
            subindex: value.subindex,
            value: value.value,
        });
    }
    let path = config.app.socket_path(
        // SAFETY: getuid has no preconditions.
        unsafe { libc::getuid() },
        std::env::var_os("RUNTIME_DIRECTORY"),
        std::env::var_os("XDG_RUNTIME_DIR"),
    );
    match crate::app::bind(&config.app, &path) {
        Ok(listener) => Ok(Some((listener, safe))),
        // The default socket taken (another ecatd on this machine) or not reachable (not
        // root): ecatd runs without the interface rather than not at all. A socket the
        // configuration names must work.
        Err(err) if config.app.socket.is_none() => {
            tracing::warn!(%err, "application interface not started: its default socket is not available; set [app] socket or --app-socket");
            Ok(None)
        }
        Err(err) => Err(err),
    }
}

/// Starts the application interface over the scanned segment; its events join the event
/// stream. A failure is logged and ecatd runs on without it.
fn start_app(
    core: &Core,
    config: &Config,
    listener: crate::app::AppListener,
    safe: Vec<crate::app::SafeValue>,
) -> Option<crate::app::AppServer> {
    match crate::app::AppServer::start(listener, Arc::clone(core.master()), &config.app, safe) {
        Ok(app) => {
            core.set_app(app.handle());
            let mut events = app.events();
            let core = core.clone();
            tokio::spawn(async move {
                loop {
                    match events.recv().await {
                        Ok(event) => {
                            core.publish_event(crate::service::view::EventView::app(&event))
                        }
                        Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => continue,
                        Err(tokio::sync::broadcast::error::RecvError::Closed) => return,
                    }
                }
            });
            Some(app)
        }
        Err(err) => {
            tracing::error!(%err, "application interface not started");
            None
        }
    }
}

/// Hands the ETG.8200 gateway to the core and starts it next to the APIs (the core logs
/// the address bound).
async fn start_gateway(core: &Core, settings: &GatewaySettings) -> Result<(), String> {
    let config = settings.gateway_config()?;
    core.set_gateway(MailboxGateway::new(core.master().clone(), config));
    core.open_gateway().await.map_err(|err| err.message)?;
    Ok(())
}

async fn bind(addr: std::net::SocketAddr, what: &str) -> Result<TcpListener, String> {
    TcpListener::bind(addr)
        .await
        .map_err(|err| format!("cannot listen for {what} on {addr}: {err}"))
}

impl Config {
    fn grpc_listen_of(&self, listener: &TcpListener) -> std::net::SocketAddr {
        listener.local_addr().unwrap_or(self.grpc_listen)
    }

    fn http_listen_of(&self, listener: &TcpListener) -> std::net::SocketAddr {
        listener.local_addr().unwrap_or(self.http_listen)
    }
}
