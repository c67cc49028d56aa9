//! One file per command group; each command is a clap `Args` struct implementing
//! [`Run`](crate::Run).

pub mod coe;
pub mod cstruct;
pub mod debug;
pub mod diag;
pub mod docs;
pub mod domains;
pub mod eoe_filter;
pub mod esc;
pub mod events;
pub mod foe;
pub mod graph;
pub mod ip;
pub mod master;
pub mod pcap;
pub mod pd;
pub mod registers;
pub mod sii;
pub mod slaves;
pub mod soe;
pub mod states;
pub mod voe;
pub mod xml;
