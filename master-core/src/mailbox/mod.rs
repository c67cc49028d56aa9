//! The mailbox engine: one owner per slave mailbox, and the CoE, SoE, FoE, VoE and EoE
//! clients on top (ETG.1000.4, spec-notes §mbx.header, §voe).
//!
//! [`MailboxEngine::start`] runs the engine on its own thread (a current-thread tokio
//! runtime) next to the bus; [`MailboxEngine::add_slave`] hands it a slave's mailbox
//! ([`SlaveMailboxConfig`], produced by the master's bring-up) and returns a
//! [`SlaveMailbox`] handle. Every protocol client is an async method on that handle and
//! works from any executor:
//!
//! | protocol | calls |
//! |---|---|
//! | CoE | [`sdo_upload`](SlaveMailbox::sdo_upload), [`sdo_download`](SlaveMailbox::sdo_download), `_complete` variants, [`sdo_info_od_list`](SlaveMailbox::sdo_info_od_list), [`sdo_info_object`](SlaveMailbox::sdo_info_object), [`sdo_info_entry`](SlaveMailbox::sdo_info_entry), [`emergencies`](SlaveMailbox::emergencies) |
//! | SoE | [`soe_read`](SlaveMailbox::soe_read), [`soe_write`](SlaveMailbox::soe_write) |
//! | FoE | [`foe_read`](SlaveMailbox::foe_read), [`foe_write`](SlaveMailbox::foe_write) |
//! | VoE | [`voe`](SlaveMailbox::voe) |
//! | EoE | [`eoe_send`](SlaveMailbox::eoe_send), [`subscribe_eoe`](SlaveMailbox::subscribe_eoe), [`eoe_set_ip`](SlaveMailbox::eoe_set_ip), [`eoe_get_ip`](SlaveMailbox::eoe_get_ip), [`eoe_set_address_filter`](SlaveMailbox::eoe_set_address_filter) |
//! | any | [`raw`](SlaveMailbox::raw), [`raw_replies`](SlaveMailbox::raw_replies), [`raw_send`](SlaveMailbox::raw_send): a mailbox type and service data in, [`RawReply`]s out (the ETG.8200 gateway) |
//!
//! # How a slave's mailbox is run
//!
//! Each slave's mailbox is taken in turns (a fair lock): a request runs in its caller's
//! own future once its turn comes, at most [`MailboxConfig::queue_len`] waiting, so a
//! transaction (a segmented SDO transfer, a whole FoE file) is never interleaved with
//! another and a request crosses no thread but the bus thread's; the slave's owner task on
//! the engine's thread takes turns for the side traffic (EoE) and for reading what the
//! slave sends on its own. Requests to different slaves run concurrently and their
//! datagrams share frames on the bus. Each request carries the next mailbox counter
//! (1..7); a write refused because the slave's receive mailbox is still full (working
//! counter 0) is written again. The send mailbox is read by polling — right after a
//! request, and every [`MailboxConfig::idle_poll`] otherwise — or at once on
//! [`MailboxEngine::notify_mailbox_full`], the hook for the mapped SM1 status bit.
//!
//! Everything read is sorted by type (spec-notes §mbx.demux): the waiting request gets its answer, CoE
//! emergencies go to a bounded history and a broadcast channel, EoE fragments to the EoE
//! receiver, SoE notifications to theirs. Nothing is dropped silently: what nobody takes
//! is counted in [`MailboxStats`].
//!
//! The bus resends lost frames, which can carry out a write twice and would let a
//! resent read of SM1 swallow a message: writes are guarded by the counter (the slave
//! discards a repetition), reads are sent once ([`BusHandle::submit_once`](crate::bus::BusHandle::submit_once)) and a lost
//! one is recovered with the repeat procedure (ETG.1000.4, spec-notes §mbx.repeat).
//!
//! Every request has a deadline ([`MailboxConfig::timeout`], or
//! [`SlaveMailbox::with_timeout`]). Dropping a request's future cancels it: a request not
//! started is skipped; one under way finishes the exchange it is in (so its answer is not
//! left for the next request) and aborts an open transfer the protocol's way (SDO abort,
//! FoE error).

mod coe;
mod config;
mod engine;
mod eoe;
mod error;
mod foe;
mod matching;
mod raw;
mod soe;
mod voe;

pub use coe::{EntryInfo, ObjectInfo};
pub use config::{MailboxArea, MailboxConfig, MailboxProtocols, SlaveMailboxConfig};
pub use engine::MailboxEngine;
pub use engine::events::{Emergency, EoeFrame, SoeNotification};
pub use engine::slave::SlaveMailbox;
pub use engine::stats::MailboxStats;
pub use eoe::IpSettings;
pub use error::{MailboxError, Result};
pub use foe::{FoeOptions, FoeProgress};
pub use raw::RawReply;
pub use voe::VoeMessage;

/// The side traffic each slave's owner task carries beside the requests: EoE. Chosen here,
/// where the engine and the protocols meet, so the engine knows only its hooks
/// ([`engine::hook`]) and the dependency points from the protocol to the engine.
fn side_traffic(config: &MailboxConfig) -> engine::hook::SideTraffic {
    eoe::side_traffic(config)
}
