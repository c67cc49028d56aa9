//! The bus: frames, datagrams and working counters through a fake segment, cyclic and
//! acyclic traffic, polling, scheduling, faults, late replies and shutdown, and the raw
//! socket link under it.

#[path = "../bus_support/mod.rs"]
mod bus_support;

mod chains;
mod cyclic;
mod faults;
mod guest;
mod late_replies;
mod polling;
mod raw_socket;
mod scheduling;
mod shutdown;
mod traffic;
