//! Process data: where a slave's process data comes from (`layout`: the SII, or CoE
//! through `coe_layout`), configured PDO assignments (`pdo_assignment`, written by `pdo_config`), the process image and
//! the cyclic task that exchanges it (`image`), slave groups with periods of their own
//! (`groups`), named entries and snapshots (`pd_entry`), bit copying (`bits`), the cycle's
//! counters (`cycle_stats`), code run on the bus thread at each cycle (`hook`), which slave a wrong working counter is put down to
//! (`wkc_blame`), and the mailbox-full bits mapped into the cyclic frame
//! (`mailbox_status`).

mod api;
pub(super) mod bits;
pub(super) mod coe_layout;
pub(super) mod cycle_stats;
pub(super) mod groups;
pub(super) mod hook;
pub(super) mod image;
pub(super) mod layout;
pub(super) mod mailbox_status;
pub(super) mod pd_entry;
pub(super) mod pdo_assignment;
pub(super) mod pdo_config;
pub(super) mod wkc_blame;
