//! Shared helpers for ecatd's end-to-end tests: network namespaces joined by a veth pair,
//! the `ecat-sim` process, the Python masters, and tshark.
//!
//! Two modules are the master-core test helpers themselves, compiled here from their one
//! source file (no second copy): [`netns`] and [`tshark`].

// The namespace helper was written for master-core's test crates, where `NetNs::new` is
// the only constructor a test wants; a `Default` would hide that it needs root.
#[allow(clippy::new_without_default)]
#[path = "../../master-core/tests/bus_support/netns.rs"]
pub mod netns;
#[path = "../../master-core/tests/tshark_support/mod.rs"]
pub mod tshark;

pub mod pysoem_session;
pub mod python;
pub mod realtime;
pub mod rig;
pub mod sim_process;
pub mod veth_master;
