//! The ETG.8200 mailbox gateway's statistics (`ecat_mailbox_gateway_*`).
//!
//! The gateway (`master_core::gateway`, its `MailboxGatewayStats`) is built by another
//! part of the project; until it lands there is nothing to export. The names it will have
//! are fixed in `docs/metrics.md` (requests, forwarded and failed requests, requests per
//! protocol, failures by reason, up, start time, request duration); they go here, read
//! from the gateway's statistics snapshot like the bus metrics in `bus.rs`.

use prometheus::proto::MetricFamily;

use crate::core::Core;

/// The gateway's families (none yet).
pub fn collect(_core: &Core) -> Vec<Option<MetricFamily>> {
    Vec::new()
}
