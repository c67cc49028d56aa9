//! master-core and the other masters against `ecat-sim` over veth: master-core's master,
//! mailboxes and process data, and pysoem, KickCAT and Wireshark on the simulator (pysoem
//! also on a ring, with its cable redundancy).

#[path = "../../../master-core/tests/master_pd_support/mod.rs"]
mod master_pd_support;

mod kickcat;
mod mailbox;
mod master;
mod process_data;
mod pysoem;
mod redundancy;
mod redundancy_pysoem;
mod tshark;
