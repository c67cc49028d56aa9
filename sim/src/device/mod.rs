//! Slave applications: what runs behind an emulated ESC's PDI.
//!
//! The ESC (`crate::esc`) owns registers, SyncManagers, FMMUs and the AL state machine; a
//! [`Device`] owns everything the slave's firmware would: the mailbox protocols and the process
//! data. The ESC calls the device synchronously while a frame passes, so a simulated segment is
//! deterministic: the same frames in give the same frames out.

use std::collections::VecDeque;

use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;

/// Process-data sizes in bytes: SM2 (outputs, master → slave) and SM3 (inputs, slave → master).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ProcessDataSizes {
    /// Bytes of outputs (SM2).
    pub outputs: u16,
    /// Bytes of inputs (SM3).
    pub inputs: u16,
}

/// What the ESC tells its device about the slave's current configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceContext {
    /// Configured station address (register 0x0010).
    pub station_address: u16,
    /// Current AL state.
    pub al_state: AlState,
    /// Length of SM0, the master → slave mailbox (0 when not configured).
    pub rx_mailbox_size: u16,
    /// Length of SM1, the slave → master mailbox (0 when not configured).
    pub tx_mailbox_size: u16,
}

/// Complete mailbox messages (header + data) a device wants to post in SM1, oldest first.
///
/// Bounded: a device that produces faster than the master reads is told so instead of growing
/// memory without limit.
#[derive(Debug)]
pub struct Outbox {
    queue: VecDeque<Vec<u8>>,
    capacity: usize,
}

/// The outbox is full; the message was not queued.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutboxFull;

impl Outbox {
    /// An empty outbox holding at most `capacity` messages.
    pub fn new(capacity: usize) -> Self {
        Outbox {
            queue: VecDeque::with_capacity(capacity.min(64)),
            capacity,
        }
    }

    /// Queues a message.
    pub fn push(&mut self, message: Vec<u8>) -> Result<(), OutboxFull> {
        if self.queue.len() >= self.capacity {
            return Err(OutboxFull);
        }
        self.queue.push_back(message);
        Ok(())
    }

    /// Takes the oldest message.
    pub fn pop(&mut self) -> Option<Vec<u8>> {
        self.queue.pop_front()
    }

    /// Messages waiting.
    pub fn len(&self) -> usize {
        self.queue.len()
    }

    /// True when nothing waits.
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Drops everything (the mailbox was reset, e.g. on a fall back to INIT).
    pub fn clear(&mut self) {
        self.queue.clear();
    }
}

/// The application behind a slave's PDI. Every method has a default, so a device implements
/// only what it has (a terminal without mailbox implements only process data).
pub trait Device: Send {
    /// A complete mailbox message (6-byte header + `length` data bytes) that the master wrote
    /// into SM0. Replies (zero or more complete messages) go into `outbox`.
    fn mailbox_received(&mut self, message: &[u8], ctx: &DeviceContext, outbox: &mut Outbox) {
        let _ = (message, ctx, outbox);
    }

    /// Called while a frame passes and SM1 is empty, so the device can post unsolicited
    /// messages (emergencies, EoE frames) or continue deferred work (FoE busy phases).
    fn poll(&mut self, ctx: &DeviceContext, outbox: &mut Outbox) {
        let _ = (ctx, outbox);
    }

    /// Process-data sizes the device expects with its current PDO assignment; the ESC checks
    /// SM2/SM3 against them on PREOP → SAFEOP.
    fn process_data_sizes(&self) -> ProcessDataSizes {
        ProcessDataSizes::default()
    }

    /// A complete SM2 buffer of outputs was written by the master.
    fn outputs_written(&mut self, outputs: &[u8]) {
        let _ = outputs;
    }

    /// Fills the SM3 buffer with the current inputs.
    fn read_inputs(&mut self, inputs: &mut [u8]) {
        let _ = inputs;
    }

    /// The master requested `to` while the slave is in `from`, and the ESC's own checks
    /// (SyncManagers, FMMUs) passed. Returning an error refuses with that AL status code.
    fn state_change(
        &mut self,
        from: AlState,
        to: AlState,
        ctx: &DeviceContext,
    ) -> Result<(), AlStatusCode> {
        let _ = (from, to, ctx);
        Ok(())
    }
}

pub mod coe;
pub mod coe_quirks;
pub mod composite;
pub mod dio;
pub mod drive;
pub mod eoe;
pub mod foe;
pub mod mailbox;
pub mod soe;
pub mod voe;

pub use coe::{CoeService, SharedDictionary};
pub use composite::SlaveDevice;
pub use drive::Drive;
pub use mailbox::{MailboxService, MailboxStack, ReplySink};
