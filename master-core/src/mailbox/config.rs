//! What the engine needs to know about a slave's mailbox, and how the engine behaves.

use std::time::Duration;

/// One mailbox SyncManager area in the slave's memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxArea {
    /// Physical start address (SM register offset 0).
    pub start: u16,
    /// Length in bytes, header included (SM register offset 2).
    pub len: u16,
}

/// The mailbox protocols a slave supports (SII word 0x1C); one type for the SII codec, the
/// master and the engine.
pub use crate::wire::sii::MailboxProtocols;

/// A slave's mailbox as the master's bring-up found it: where SM0 and SM1 are and which
/// protocols the slave speaks. The bring-up produces one per mailbox slave (from the SII and
/// the SyncManager configuration it wrote) and hands them to
/// [`MailboxEngine::add_slave`](super::MailboxEngine::add_slave).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlaveMailboxConfig {
    /// Configured station address (register 0x0010).
    pub station: u16,
    /// SM0, the master → slave mailbox ("write mailbox").
    pub write: MailboxArea,
    /// SM1, the slave → master mailbox ("read mailbox").
    pub read: MailboxArea,
    /// Protocols from SII word 0x1C.
    pub protocols: MailboxProtocols,
}

/// How the engine behaves; the defaults suit a real segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxConfig {
    /// Deadline of a request that does not set its own, counted from the call. It covers
    /// queueing, every exchange of a multi-message transfer and the slave's answers, so a
    /// 1 MiB FoE transfer needs a longer one ([`SlaveMailbox::with_timeout`](super::SlaveMailbox::with_timeout)).
    /// Default 3 s (IgH waits 1-3 s for CoE/FoE answers).
    pub timeout: Duration,
    /// Requests one slave queues while it works on another; a request to a full queue
    /// fails at once with [`MailboxError::QueueFull`](super::MailboxError::QueueFull), as
    /// the bus does. Default 64.
    pub queue_len: usize,
    /// Ethernet frames queued for sending over EoE per slave; sending to a full queue fails
    /// at once, as a network interface drops. Default 16.
    pub eoe_tx_queue_len: usize,
    /// How often an idle slave's send mailbox is read, to pick up emergencies, EoE frames
    /// and SoE notifications; `None` reads it only while a request waits for an answer
    /// (and when [`MailboxEngine::notify_mailbox_full`](super::MailboxEngine::notify_mailbox_full) says so). Default 10 ms.
    pub idle_poll: Option<Duration>,
    /// Longest pause between reads of the send mailbox while an answer is awaited. After
    /// the first few immediate reads ([`MailboxConfig::eager_polls`]) the pauses start at
    /// 50 µs and grow by half each read up to this, so a slave that answers after a delay
    /// is read at most about half that delay late and a few times per exchange. A
    /// "mailbox full" notice ([`MailboxEngine::notify_mailbox_full`](super::MailboxEngine::notify_mailbox_full))
    /// ends a pause at once. Default 1 ms.
    pub poll_interval: Duration,
    /// Reads of the send mailbox made back to back after the one that goes in the request's
    /// own frame, before the pauses start: on a veth link they cover the first 100-200 µs,
    /// where a pause would cost more in thread wake-ups than the reads. The bus thread makes
    /// them itself, each in the next frame out, while SM1 is empty
    /// ([`BusHandle::submit_once_polling`](crate::bus::BusHandle::submit_once_polling)).
    /// Default 4.
    pub eager_polls: u32,
    /// Pause before the request is written again when the slave's receive mailbox is still
    /// full. Default 1 ms.
    pub full_retry_interval: Duration,
    /// Emergencies kept per slave ([`SlaveMailbox::emergencies`](super::SlaveMailbox::emergencies)). Default 32.
    pub emergency_history: usize,
    /// Events (emergencies, EoE frames, SoE notifications) a subscriber may fall behind by
    /// before it misses some (and is told how many). Default 64.
    pub event_capacity: usize,
    /// A partly received EoE frame is dropped when its next fragment does not come within
    /// this time. Default 1 s.
    pub eoe_fragment_timeout: Duration,
    /// Largest SDO upload or SoE read accepted (a slave announcing more gets an abort).
    /// Default 16 MiB.
    pub max_value_len: usize,
    /// Largest FoE file read accepted. Default 64 MiB.
    pub max_file_len: usize,
}

impl Default for MailboxConfig {
    fn default() -> MailboxConfig {
        MailboxConfig {
            timeout: Duration::from_secs(3),
            queue_len: 64,
            eoe_tx_queue_len: 16,
            idle_poll: Some(Duration::from_millis(10)),
            poll_interval: Duration::from_millis(1),
            eager_polls: 4,
            full_retry_interval: Duration::from_millis(1),
            emergency_history: 32,
            event_capacity: 64,
            eoe_fragment_timeout: Duration::from_secs(1),
            max_value_len: 16 << 20,
            max_file_len: 64 << 20,
        }
    }
}
