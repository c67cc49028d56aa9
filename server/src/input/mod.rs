//! How callers write slaves, values and EoE IP settings (in a request body, a URL, a
//! command-line flag or the configuration file), parsed into master-core's types, with the
//! [`ApiError`](crate::error::ApiError) that names what was wrong.
//!
//! Below every runtime module: the configuration, the service core and both APIs read these
//! forms, and none of them is imported here. Files: `address` (slave names: `3`, `#0x1001`,
//! `@7`, `alias:offset`), `value` (numbers and typed values), `ip` (dotted quads and colon
//! MACs to [`IpSettings`](master_core::mailbox::IpSettings)), `state` (AL state names),
//! `since` (a time or a span back from now).

pub mod address;
pub mod ip;
pub mod mac_filter;
pub mod since;
pub mod soe_value;
pub mod state;
pub mod value;
