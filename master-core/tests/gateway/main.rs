//! The ETG.8200 mailbox gateway: its wire, sessions, roles, workers, retries and late
//! replies, every mailbox protocol through it, the master's own dictionary, and compatibility
//! with other gateway clients.

#[path = "../gateway_support/compat_client.rs"]
mod compat_client;
#[path = "../gateway_support/mod.rs"]
mod gateway_support;

mod coe;
mod compat;
mod errors;
mod late_replies;
mod load;
mod master_od;
mod protocols;
mod retries;
mod robustness;
mod roles;
mod service;
mod sessions;
mod tcp;
mod workers;
