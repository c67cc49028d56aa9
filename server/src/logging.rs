//! Structured logs with `tracing`, human-readable or JSON, to standard error; and the audit
//! lines (target `audit`, from the APIs and the mailbox gateway) to their own sink, as JSON
//! lines whatever the log filter says, so `--log warn` never hides who wrote what.

use std::path::Path;

use tracing::level_filters::LevelFilter;
use tracing_subscriber::filter::{EnvFilter, Targets};
use tracing_subscriber::prelude::*;

use crate::config::LogFormat;

/// The tracing target of the audit lines.
pub const AUDIT_TARGET: &str = "audit";

/// Installs the global subscriber; `filter` uses `EnvFilter` syntax. Audit lines go to
/// `audit_log` (appended) or, without one, to standard error as JSON lines.
pub fn init(format: LogFormat, filter: &str, audit_log: Option<&Path>) -> Result<(), String> {
    // The audit target is the audit sink's alone: the log filter neither shows it twice
    // nor hides it.
    let filter = EnvFilter::try_new(filter)
        .map_err(|err| format!("bad log filter: {err}"))?
        .add_directive(
            format!("{AUDIT_TARGET}=off")
                .parse()
                .map_err(|err| format!("bad log filter: {err}"))?,
        );
    let log = tracing_subscriber::fmt::layer().with_writer(std::io::stderr);
    let log = match format {
        LogFormat::Human => log.boxed(),
        LogFormat::Json => log.json().boxed(),
    }
    .with_filter(filter);
    let audit = tracing_subscriber::fmt::layer().json();
    let audit = match audit_log {
        Some(path) => {
            let file = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(path)
                .map_err(|err| format!("cannot open the audit log {}: {err}", path.display()))?;
            audit.with_writer(std::sync::Mutex::new(file)).boxed()
        }
        None => audit.with_writer(std::io::stderr).boxed(),
    }
    .with_filter(Targets::new().with_target(AUDIT_TARGET, LevelFilter::TRACE));
    tracing_subscriber::registry()
        .with(log)
        .with(audit)
        .try_init()
        .map_err(|err| format!("cannot install the logger: {err}"))
}
