//! SIGINT and SIGTERM: the first starts the shutdown, a second one exits at once.

use tokio::signal::unix::{Signal, SignalKind, signal};

/// The process's SIGINT and SIGTERM handlers.
pub struct Signals {
    term: Signal,
    int: Signal,
}

impl Signals {
    /// Installs the handlers (from then on the signals no longer kill the process).
    pub fn install() -> Result<Signals, String> {
        let install = |kind: SignalKind, name: &str| {
            signal(kind).map_err(|err| format!("cannot handle {name}: {err}"))
        };
        Ok(Signals {
            term: install(SignalKind::terminate(), "SIGTERM")?,
            int: install(SignalKind::interrupt(), "SIGINT")?,
        })
    }

    /// Waits for the next signal and names it.
    pub async fn next(&mut self) -> &'static str {
        tokio::select! {
            _ = self.term.recv() => "SIGTERM",
            _ = self.int.recv() => "SIGINT",
        }
    }

    /// From now on, the next signal ends the process at once with the shell's code for it
    /// (128 + the signal number).
    pub fn exit_on_next(mut self) {
        tokio::spawn(async move {
            let signal = self.next().await;
            tracing::warn!(signal, "second signal: exiting at once");
            let code = if signal == "SIGINT" { 130 } else { 143 };
            std::process::exit(code);
        });
    }
}
