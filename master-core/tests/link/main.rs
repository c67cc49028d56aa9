//! Links: the in-memory and raw-socket links, fault injection and the pcap tap.

#[path = "../bus_support/mod.rs"]
mod bus_support;

mod fault;
mod memory;
mod pcap;
mod raw_socket;
