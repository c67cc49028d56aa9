//! The suite of `server_gateway_compat.rs` again, with ecatd on a real interface: `ecatd
//! --iface` on a veth pair whose other end is `ecat-sim` (the same topology) in its own
//! namespace. See `server_support::on_veth`.

#[path = "server_gateway_compat.rs"]
mod suite;
