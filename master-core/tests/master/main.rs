//! The master: scan, topology, slave configuration, AL states and startup aborts, process
//! data (layout, assignment, image, groups, statistics), DC, diagnostics, faults, the
//! safe state and captures checked by Wireshark.

#[path = "../master_pd_support/mod.rs"]
mod master_pd_support;
#[path = "../master_support/mod.rs"]
mod master_support;
#[path = "../tshark_support/mod.rs"]
#[allow(dead_code)]
mod tshark;

mod capture;
mod dc;
mod dc_assign;
mod dc_power;
mod diagnostics;
mod faults;
mod mailbox;
mod pd_assign;
mod pd_groups;
mod pd_image;
mod pd_layout;
mod pd_mailbox_status;
mod pd_stats;
mod redundancy;
mod safe_state;
mod scan;
mod slave_config;
mod startup_aborts;
mod topology;
