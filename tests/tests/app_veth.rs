//! The suite of `app.rs` again, with ecatd on a real interface: `ecatd --iface` on a veth
//! pair whose other end is `ecat-sim --control` (the same topology) in its own namespace;
//! the outputs are read from the simulator's reports. See `server_support::on_veth`.

#[path = "app.rs"]
mod suite;
