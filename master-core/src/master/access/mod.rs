//! Reaching one slave: naming it (`address`), the register datagrams that expect exactly
//! that slave to answer (`datagram`), and the register/SII/alias access offered to tools
//! (`tools`).

pub(super) mod address;
mod api;
pub(super) mod datagram;
pub(super) mod tools;
