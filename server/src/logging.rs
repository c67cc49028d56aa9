//! Structured logs with `tracing`, human-readable or JSON, to standard error; and the audit
//! lines (target `audit`, from the APIs and the mailbox gateway) to their own sink, as JSON
//! lines whatever the log filter says, so `--log warn` never hides who wrote what.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::{Mutex, OnceLock, PoisonError};

use tracing::level_filters::LevelFilter;
use tracing_subscriber::filter::{EnvFilter, Targets};
use tracing_subscriber::prelude::*;
use tracing_subscriber::{Registry, reload};

use crate::config::LogFormat;

/// The tracing target of the audit lines.
pub const AUDIT_TARGET: &str = "audit";

/// The log filter in force and the handle that replaces it at run time (`ecat debug`);
/// set once by [`init`].
struct Runtime {
    filter: Mutex<String>,
    handle: reload::Handle<EnvFilter, Registry>,
}

static RUNTIME: OnceLock<Runtime> = OnceLock::new();

/// The tracing targets of ecatd's own crates (binaries and libraries).
const OWN_TARGETS: [&str; 6] = ["ecatd", "ecat", "server", "master_core", "sim", "ecat_app"];

/// `filter` with a bare `debug` or `trace` level scoped to ecatd's own crates: the other
/// crates (h2, hyper, tonic, ...) stay at `warn` unless a directive names them. Without
/// this, `--log debug` is almost all HTTP/2 frame dumps. `info` and quieter levels, and
/// every directive with a target, are kept as written.
fn scoped(filter: &str) -> String {
    let directives: Vec<&str> = filter
        .split(',')
        .map(str::trim)
        .filter(|d| !d.is_empty())
        .collect();
    // Targets the filter names itself keep their own level.
    let named: Vec<&str> = directives
        .iter()
        .filter_map(|d| d.split_once('=').map(|(target, _)| target.trim()))
        .collect();
    let mut out = Vec::new();
    for directive in directives {
        let verbose = ["debug", "trace"]
            .iter()
            .any(|level| directive.eq_ignore_ascii_case(level));
        if verbose {
            out.push("warn".to_owned());
            let level = directive.to_ascii_lowercase();
            out.extend(
                OWN_TARGETS
                    .iter()
                    .filter(|target| !named.contains(target))
                    .map(|target| format!("{target}={level}")),
            );
        } else {
            out.push(directive.to_owned());
        }
    }
    out.join(",")
}

/// The filter as the log layer uses it: the audit target is the audit sink's alone, so the
/// log filter neither shows it twice nor hides it; a bare verbose level is [`scoped`].
fn log_filter(filter: &str) -> Result<EnvFilter, String> {
    let audit_off = format!("{AUDIT_TARGET}=off")
        .parse()
        .map_err(|err| format!("bad log filter: {err}"))?;
    Ok(EnvFilter::try_new(scoped(filter))
        .map_err(|err| format!("bad log filter: {err}"))?
        .add_directive(audit_off))
}

/// The log filter in force; `None` when [`init`] has not run (a library user's process).
pub fn current_filter() -> Option<String> {
    RUNTIME.get().map(|r| {
        r.filter
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    })
}

/// Replaces the log filter (`EnvFilter` syntax) at run time. A bad filter is refused and
/// the old one stays; `Err(None)` when [`init`] has not run.
pub fn set_filter(filter: &str) -> Result<(), Option<String>> {
    let runtime = RUNTIME.get().ok_or(None)?;
    let parsed = log_filter(filter).map_err(Some)?;
    let mut current = runtime
        .filter
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    runtime
        .handle
        .reload(parsed)
        .map_err(|err| Some(format!("cannot replace the log filter: {err}")))?;
    *current = filter.to_owned();
    Ok(())
}

/// Installs the global subscriber; `filter` uses `EnvFilter` syntax. Audit lines go to
/// `audit_log` (appended) or, without one, to standard error as JSON lines.
pub fn init(format: LogFormat, filter: &str, audit_log: Option<&Path>) -> Result<(), String> {
    let text = filter.to_owned();
    let (filter, handle) = reload::Layer::new(log_filter(filter)?);
    // Colours only on a terminal: under systemd the journal (or a pipe) would keep the
    // escape codes in every line.
    let log = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal());
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
        .map_err(|err| format!("cannot install the logger: {err}"))?;
    let _ = RUNTIME.set(Runtime {
        filter: Mutex::new(text),
        handle,
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bare_verbose_level_is_ecatds_own_and_named_targets_keep_theirs() {
        assert_eq!(
            scoped("debug"),
            "warn,ecatd=debug,ecat=debug,server=debug,master_core=debug,sim=debug,ecat_app=debug"
        );
        assert_eq!(
            scoped("TRACE,h2=debug,server=info"),
            "warn,ecatd=trace,ecat=trace,master_core=trace,sim=trace,ecat_app=trace,h2=debug,\
             server=info"
        );
        for kept in ["info", "warn", "master_core::bus=trace", "info,tower=debug"] {
            assert_eq!(scoped(kept), kept);
        }
        // What the layer builds from them parses.
        for filter in ["debug", "trace,h2=debug", "info"] {
            assert!(log_filter(filter).is_ok(), "{filter}");
        }
    }
}
