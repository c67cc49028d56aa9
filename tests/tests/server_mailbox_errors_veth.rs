//! The suite of `server_mailbox_errors.rs` again, with ecatd on a real interface: `ecatd
//! --iface` on a veth pair whose other end is `ecat-sim` (the same topology file, with its
//! firmware switches) in its own namespace. See `server_support::on_veth`.

#[path = "server_mailbox_errors.rs"]
mod suite;
