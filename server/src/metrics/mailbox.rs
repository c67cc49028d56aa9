//! Mailbox metrics per slave (station label): requests, failures, traffic, EoE frames.

use master_core::mailbox::MailboxStats;
use prometheus::proto::{MetricFamily, MetricType};

use super::family::Family;
use crate::service::Core;

type Field = fn(&MailboxStats) -> u64;

const COUNTERS: [(&str, &str, Field); 14] = [
    (
        "ecat_mailbox_requests_total",
        "Mailbox requests (CoE, SoE, FoE, VoE, EoE calls).",
        |s| s.requests,
    ),
    (
        "ecat_mailbox_failed_requests_total",
        "Mailbox requests that failed.",
        |s| s.failed,
    ),
    (
        "ecat_mailbox_cancelled_requests_total",
        "Mailbox requests cancelled by their caller.",
        |s| s.cancelled,
    ),
    (
        "ecat_mailbox_writes_total",
        "Messages written to the slave's receive mailbox.",
        |s| s.writes,
    ),
    (
        "ecat_mailbox_write_full_total",
        "Writes the slave did not take: its receive mailbox was still full (written again).",
        |s| s.write_full,
    ),
    (
        "ecat_mailbox_reads_total",
        "Messages read from the slave's send mailbox.",
        |s| s.reads,
    ),
    (
        "ecat_mailbox_repeats_total",
        "Mailbox repeat requests after a lost read.",
        |s| s.repeats,
    ),
    (
        "ecat_mailbox_malformed_total",
        "Malformed messages from the slave.",
        |s| s.malformed,
    ),
    (
        "ecat_mailbox_emergencies_total",
        "CoE emergencies received.",
        |s| s.emergencies,
    ),
    (
        "ecat_eoe_frames_received_total",
        "Ethernet frames received from the slave over EoE.",
        |s| s.eoe_frames_in,
    ),
    (
        "ecat_eoe_frames_sent_total",
        "Ethernet frames sent to the slave over EoE.",
        |s| s.eoe_frames_out,
    ),
    (
        "ecat_eoe_received_bytes_total",
        "Bytes of the Ethernet frames received from the slave over EoE.",
        |s| s.eoe_bytes_in,
    ),
    (
        "ecat_eoe_sent_bytes_total",
        "Bytes of the Ethernet frames sent to the slave over EoE.",
        |s| s.eoe_bytes_out,
    ),
    (
        "ecat_eoe_reassembly_errors_total",
        "EoE fragments that could not be reassembled.",
        |s| s.eoe_reassembly_errors,
    ),
];

/// The mailbox families.
pub fn collect(core: &Core) -> Vec<Option<MetricFamily>> {
    let engine = core.master().mailbox_engine();
    let stats: Vec<(String, MailboxStats)> = engine
        .stations()
        .into_iter()
        .filter_map(|station| Some((station.to_string(), engine.slave(station).ok()?.stats())))
        .collect();
    COUNTERS
        .iter()
        .map(|(name, help, field)| {
            stats
                .iter()
                .fold(
                    Family::new(name, help, MetricType::COUNTER),
                    |f, (station, s)| f.counter(&[("station", station)], field(s) as f64),
                )
                .done()
        })
        .collect()
}
