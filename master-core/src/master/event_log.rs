//! One log line per segment event, so that an operator at the default level (`info`) sees
//! every bus fault as it happens: a slave lost or found again, replaced, an AL error with
//! its code and name (an SM watchdog is AL status code 0x001B), a topology mismatch, a failed
//! start-up command; state changes at `info` too. Faults are `warn`. A flapping cable can
//! raise these without limit: they share one bucket ([`LogLimit`]) large enough for a
//! whole segment lost at once, and what it holds back is counted in the next line.

use std::time::{Duration, Instant};

use crate::log_limit::LogLimit;
use crate::master::event::MasterEvent;

/// Lines at once: every slave of a large segment lost together.
const BURST: u32 = 256;
/// Then one line per this.
const REFILL: Duration = Duration::from_millis(100);

/// The bucket the master's event lines share.
pub(crate) fn limit() -> LogLimit {
    LogLimit::new(BURST, REFILL)
}

/// Logs `event` if `limit` lets it.
pub(crate) fn log(limit: &LogLimit, event: &MasterEvent) {
    let Some(suppressed) = limit.admit(Instant::now()) else {
        return;
    };
    match event {
        MasterEvent::SlaveFound {
            position,
            station,
            identity,
            name,
        } => tracing::info!(
            position,
            station,
            name,
            vendor_id = identity.vendor_id,
            product_code = identity.product_code,
            suppressed,
            "slave found"
        ),
        MasterEvent::SlaveLost {
            position,
            station,
            name,
        } => tracing::warn!(position, station, name, suppressed, "slave lost"),
        MasterEvent::SlaveReplaced {
            position,
            station,
            old,
            new,
            name,
        } => tracing::warn!(
            position,
            station,
            name,
            old_product_code = old.product_code,
            new_product_code = new.product_code,
            suppressed,
            "slave replaced by another device"
        ),
        MasterEvent::StateChanged {
            position,
            station,
            from,
            to,
        } => tracing::info!(position, station, %from, %to, suppressed, "slave state changed"),
        MasterEvent::AlError {
            position,
            station,
            name,
            state,
            code,
        } => tracing::warn!(
            position, station, name, %state, code = format_args!("{:#06x}", u16::from(*code)),
            error = code.description(), suppressed, "AL error"
        ),
        MasterEvent::TopologyMismatch {
            position,
            station,
            problem,
        } => tracing::warn!(position, station, %problem, suppressed, "topology mismatch"),
        MasterEvent::StartupFailed {
            position,
            station,
            transition,
            command,
            error,
            ..
        } => tracing::warn!(
            position,
            station,
            transition,
            command,
            error,
            suppressed,
            "start-up command failed"
        ),
    }
}
