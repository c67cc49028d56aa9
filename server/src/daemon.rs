//! Start-up and shutdown: open the segment, scan it, serve both APIs, and on SIGINT or
//! SIGTERM stop serving, bring the slaves to a safe state (INIT) and close the link.

use std::sync::Arc;
use std::time::Duration;

use master_core::wire::register::AlState;
use tokio::net::TcpListener;
use tokio::sync::watch;

use master_core::gateway::MailboxGateway;

use crate::config::{Config, GatewaySettings};
use crate::security::Tokens;
use crate::service::Core;
use crate::{grpc, http, segment};

/// How long shutdown waits for the slaves to reach the safe state.
const SAFE_STATE_TIMEOUT: Duration = Duration::from_secs(10);

/// Runs ecatd with `config` until a signal; errors are start-up failures.
pub async fn run(config: Config) -> Result<(), String> {
    config.check()?;
    let segment_config = config
        .segment
        .clone()
        .ok_or("no segment: pass --simulate [TOPOLOGY] or --iface NAME")?;
    // Bind first so a taken port fails fast, before the segment is touched.
    let grpc_listener = bind(config.grpc_listen, "gRPC").await?;
    let http_listener = bind(config.http_listen, "HTTP").await?;
    let tls = config
        .tls
        .as_ref()
        .map(crate::tls::TlsFiles::load)
        .transpose()?;
    let running = segment::open(&segment_config)?;
    // What the metrics record lives beside the core; the core only records its requests.
    let metrics = Arc::new(crate::metrics::Store::default());
    let core = Core::new(running.master.clone(), Arc::clone(&metrics.calls));
    let tokens = Tokens::new(config.tokens.clone());
    tracing::info!(
        grpc = %config.grpc_listen_of(&grpc_listener),
        http = %config.http_listen_of(&http_listener),
        tokens = tokens.enabled(),
        tls = tls.is_some(),
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
        tls.as_ref().map(crate::tls::TlsFiles::grpc),
        stopped(stop_rx.clone()),
    ));
    let app = http::router(
        core.clone(),
        tokens,
        Arc::clone(&metrics),
        running.sim.clone(),
    );
    let http_task = match &tls {
        Some(files) => tokio::spawn(http::serve_tls(
            app,
            crate::tls::TlsListener::new(http_listener, files.http()?),
            stopped(stop_rx),
        )),
        None => tokio::spawn(http::serve(app, http_listener, stopped(stop_rx))),
    };

    match core.master().scan().await {
        Ok(report) => {
            for failure in &report.failures {
                tracing::warn!(%failure, "slave did not reach its target state");
            }
            tracing::info!(slaves = report.slaves.len(), "segment scanned");
        }
        Err(err) => tracing::error!(%err, "scan failed; the APIs stay up, retry with Rescan"),
    }
    core.master().start_watch(Duration::from_millis(100));
    let background = crate::metrics::start(&core, &metrics, &config.watch);
    if let Some(settings) = &config.gateway
        && let Err(err) = start_gateway(&core, settings).await
    {
        tracing::error!(%err, "mailbox gateway not started");
    }
    core.set_ready(true);
    tracing::info!("ready");

    let signal = wait_for_signal().await;
    tracing::info!(signal, "shutting down");
    core.set_ready(false);
    let _ = stop_tx.send(true);
    for (name, task) in [("gRPC", grpc_task), ("HTTP", http_task)] {
        match task.await {
            Ok(Ok(())) => {}
            Ok(Err(err)) => tracing::error!(%err, "{name} server failed"),
            Err(err) => tracing::error!(%err, "{name} server task failed"),
        }
    }
    if let Some(mut gateway) = core.take_gateway() {
        // Stopping joins the gateway's thread: off the async workers.
        let _ = tokio::task::spawn_blocking(move || gateway.stop()).await;
    }
    drop(background);
    core.master().stop_watch();
    if tokio::time::timeout(SAFE_STATE_TIMEOUT, core.all_to(AlState::Init))
        .await
        .is_err()
    {
        tracing::warn!("slaves did not all reach INIT in time");
    }
    drop(core);
    running.stop();
    tracing::info!("stopped");
    Ok(())
}

/// Hands the ETG.8200 gateway to the core and starts it next to the APIs (the core logs
/// the address bound).
async fn start_gateway(core: &Core, settings: &GatewaySettings) -> Result<(), String> {
    let config = settings.gateway_config()?;
    core.set_gateway(MailboxGateway::new(core.master().clone(), config));
    core.start_gateway().await.map_err(|err| err.message)?;
    Ok(())
}

async fn bind(addr: std::net::SocketAddr, what: &str) -> Result<TcpListener, String> {
    TcpListener::bind(addr)
        .await
        .map_err(|err| format!("cannot listen for {what} on {addr}: {err}"))
}

async fn wait_for_signal() -> &'static str {
    use tokio::signal::unix::{SignalKind, signal};
    let (mut term, mut int) = match (
        signal(SignalKind::terminate()),
        signal(SignalKind::interrupt()),
    ) {
        (Ok(term), Ok(int)) => (term, int),
        _ => {
            // Without signal handlers, Ctrl-C through tokio's portable handler still works.
            let _ = tokio::signal::ctrl_c().await;
            return "SIGINT";
        }
    };
    tokio::select! {
        _ = term.recv() => "SIGTERM",
        _ = int.recv() => "SIGINT",
    }
}

impl Config {
    fn grpc_listen_of(&self, listener: &TcpListener) -> std::net::SocketAddr {
        listener.local_addr().unwrap_or(self.grpc_listen)
    }

    fn http_listen_of(&self, listener: &TcpListener) -> std::net::SocketAddr {
        listener.local_addr().unwrap_or(self.http_listen)
    }
}
