//! ecatd's runtime log filter (`ecat debug`, IgH's `ethercat debug`): read and replaced
//! through [`crate::logging`]'s reload handle, without a restart.

use super::{ApiError, Core, Operation, Result, Ticket};

impl Core {
    /// The log filter in force (`EnvFilter` syntax).
    pub fn log_filter(&self) -> Result<String> {
        crate::logging::current_filter().ok_or_else(not_installed)
    }

    /// Replaces the log filter; a bad filter is refused and the old one stays.
    pub fn set_log_filter(&self, mut ticket: Ticket, filter: &str) -> Result<String> {
        ticket.check(Operation::SetLogFilter, "ecatd")?;
        ticket.value(filter.as_bytes());
        ticket.finish(set_filter(filter))
    }
}

fn set_filter(filter: &str) -> Result<String> {
    let filter = filter.trim();
    if filter.is_empty() {
        return Err(ApiError::invalid_field(
            "filter",
            "give a filter: a level (\"debug\") or directives (\"info,master_core::bus=trace\")",
        ));
    }
    crate::logging::set_filter(filter).map_err(|err| match err {
        Some(message) => ApiError::invalid_field("filter", message),
        None => not_installed(),
    })?;
    tracing::info!(filter, "log filter replaced");
    Ok(filter.to_owned())
}

fn not_installed() -> ApiError {
    ApiError::unavailable("this process has no reloadable log filter (its logger is not ecatd's)")
}
