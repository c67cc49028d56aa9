//! ecatd, the EtherCAT master daemon: configuration, the service layer (`service`) and the
//! APIs over it (gRPC in `grpc`, REST/metrics/health in `http`), security, and start-up.
//!
//! Binaries: `ecatd` (the daemon, `src/main.rs`) and `ecat` (the command-line client). A
//! control program that owns the master itself runs the same servers in its own process
//! through [`embed`].

pub mod app;
pub mod audit;
pub mod config;
pub mod connections;
pub mod daemon;
pub mod embed;
pub mod eoe;
pub mod error;
pub mod exit;
/// The input parsers driven by arbitrary bytes, for the fuzz target `server_input`.
#[doc(hidden)]
pub mod fuzzing;
pub mod grpc;
pub mod http;
pub mod input;
pub mod logging;
pub mod metrics;
pub mod scheduling;
pub mod security;
pub mod segment;
pub mod service;
pub mod signals;
pub mod sim_hooks;
pub mod systemd;
pub mod tls;
pub mod watch;
