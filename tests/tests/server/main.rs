//! ecatd end to end on its embedded simulated segment (`ecatd --simulate`): every API
//! (gRPC, REST, the gateway, the CLI, metrics, events, watches, TLS, tokens, audit, limits),
//! the application interface, EoE, cable redundancy and the dashboard in a browser.

#[path = "../../../master-core/tests/gateway_support/compat_client.rs"]
mod compat_client;
#[path = "../eoe_support/mod.rs"]
mod eoe_support;
#[path = "../server_support/mod.rs"]
mod server_support;

mod app;
mod audit;
mod auth;
mod call_it;
mod capture;
mod cli;
mod cli_failures;
mod cli_igh;
mod embedded;
mod eoe;
mod error_classes;
mod events;
mod gateway;
mod gateway_compat;
mod gateway_roles;
mod grpc;
mod lifecycle;
mod limits;
mod mailbox_errors;
mod metrics;
mod redundancy;
mod rest;
mod scheduling;
mod tls;
mod watch;
mod web_dashboard;
