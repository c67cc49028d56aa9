//! ecatd end to end on a real interface: `ecatd --iface` on a veth pair whose other end is
//! `ecat-sim` in its own namespace, serving the same topology as `--simulate`. The suites of
//! the `server` binary run again here (see `server_support::on_veth`), beside the tests that
//! need a real link: configuration, a cut cable, large transfers and EoE through TAPs.

#[path = "../../../master-core/tests/gateway_support/compat_client.rs"]
mod compat_client;
#[path = "../eoe_support/mod.rs"]
mod eoe_support;
#[path = "../server_support/mod.rs"]
mod server_support;

// The suites of `server`, again.
#[path = "../server/app.rs"]
mod app;
#[path = "../server/auth.rs"]
mod auth;
#[path = "../server/cli.rs"]
mod cli;
#[path = "../server/events.rs"]
mod events;
#[path = "../server/gateway.rs"]
mod gateway;
#[path = "../server/gateway_compat.rs"]
mod gateway_compat;
#[path = "../server/grpc.rs"]
mod grpc;
#[path = "../server/lifecycle.rs"]
mod lifecycle;
#[path = "../server/mailbox_errors.rs"]
mod mailbox_errors;
#[path = "../server/metrics.rs"]
mod metrics;
#[path = "../server/rest.rs"]
mod rest;
#[path = "../server/tls.rs"]
mod tls;
#[path = "../server/watch.rs"]
mod watch;

// Only on a real link.
mod config;
mod eoe;
mod link_cut;
mod transfer;
