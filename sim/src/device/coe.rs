//! CoE for a simulated slave: the master-core SDO server ([`SdoServer`]) behind the mailbox
//! layer, answering against the slave's own [`StaticDictionary`].
//!
//! The dictionary sits behind a shared handle ([`SharedDictionary`]) because two parties use
//! it: the SDO server (the master's view through the mailbox) and the device application
//! that owns it (the drive reads 0x1C12/0x1C13 and the mapped objects for its process data).
//! Both run on the thread that passes frames through the segment, so the lock is never
//! contended; it exists to satisfy `Send`, and so a test can keep a handle.
//!
//! Emergencies (spec-notes §coe.emcy) are unsolicited: [`CoeService::raise_emergency`] queues one and
//! the next [`MailboxService::poll`] posts it, so it reaches SM1 only when the master may
//! read, as on a real slave.

use std::any::Any;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

use ecat_od::emergency::emergency;
use ecat_od::{Outcome, SdoServer, ServerContext, StaticDictionary};
use ecat_wire::coe::emergency::EMERGENCY_LEN;
use ecat_wire::mailbox::{MailboxErrorCode, MailboxHeader, MailboxType};

use crate::device::coe_quirks::CoeQuirks;
use crate::device::{DeviceContext, MailboxService, ReplySink};

/// A dictionary shared between the CoE service and the device that owns it.
pub type SharedDictionary = Arc<Mutex<StaticDictionary>>;

/// Locks a shared dictionary; a poisoned lock (a panicking test thread) still yields it.
pub fn lock_dictionary(dict: &SharedDictionary) -> MutexGuard<'_, StaticDictionary> {
    dict.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Emergencies a slave keeps before it drops new ones (a real slave's queue is small too).
const EMERGENCY_QUEUE: usize = 16;

#[derive(Debug, Default)]
struct EmergencyQueue {
    pending: VecDeque<[u8; EMERGENCY_LEN]>,
    dropped: u64,
}

/// Raises emergencies on a CoE slave from outside its mailbox (a test, the topology's
/// handles): a clone of the service's own queue, posted at the service's next poll.
#[derive(Debug, Clone, Default)]
pub struct EmergencyTrigger(Arc<Mutex<EmergencyQueue>>);

impl EmergencyTrigger {
    fn lock(&self) -> MutexGuard<'_, EmergencyQueue> {
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Queues an emergency (error code, error register 0x1001, 5 manufacturer bytes) to be
    /// posted on the slave's next poll. Returns `false` when the queue is full and it was
    /// dropped, as a real slave's small queue would.
    pub fn raise(&self, code: u16, register: u8, data: [u8; 5]) -> bool {
        let mut queue = self.lock();
        if queue.pending.len() >= EMERGENCY_QUEUE {
            queue.dropped += 1;
            return false;
        }
        queue.pending.push_back(emergency(code, register, data));
        true
    }

    /// Emergencies waiting for the next poll.
    pub fn pending(&self) -> usize {
        self.lock().pending.len()
    }

    /// Emergencies dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.lock().dropped
    }

    fn pop(&self) -> Option<[u8; EMERGENCY_LEN]> {
        self.lock().pending.pop_front()
    }
}

/// The CoE mailbox service: SDO transfers, SDO Information and emergencies.
#[derive(Debug)]
pub struct CoeService {
    dict: SharedDictionary,
    server: SdoServer,
    emergencies: EmergencyTrigger,
    refused: u64,
    quirks: CoeQuirks,
}

impl CoeService {
    /// A service answering against `dict`.
    pub fn new(dict: StaticDictionary) -> Self {
        Self::shared(Arc::new(Mutex::new(dict)))
    }

    /// A service answering against a dictionary the caller also holds.
    pub fn shared(dict: SharedDictionary) -> Self {
        CoeService {
            dict,
            server: SdoServer::new(),
            emergencies: EmergencyTrigger::default(),
            refused: 0,
            quirks: CoeQuirks::default(),
        }
    }

    /// Answers as a stack with `quirks` would (aborts in service 2, short SDO
    /// Information errors, ...).
    pub fn with_quirks(mut self, quirks: CoeQuirks) -> Self {
        self.quirks = quirks;
        self
    }

    /// The shared dictionary handle.
    pub fn dictionary(&self) -> SharedDictionary {
        Arc::clone(&self.dict)
    }

    /// Successful SDO downloads to object `index` (a complete-access download counts once).
    pub fn write_count(&self, index: u16) -> u32 {
        lock_dictionary(&self.dict).write_count(index)
    }

    /// Successful SDO downloads that wrote `index:subindex`.
    pub fn entry_write_count(&self, index: u16, subindex: u8) -> u32 {
        lock_dictionary(&self.dict).entry_write_count(index, subindex)
    }

    /// Queues an emergency (error code, error register 0x1001, 5 manufacturer bytes) to be
    /// posted on the next poll. Returns `false` when the queue is full and it was dropped.
    pub fn raise_emergency(&mut self, code: u16, register: u8, data: [u8; 5]) -> bool {
        self.emergencies.raise(code, register, data)
    }

    /// A handle that raises emergencies on this service from outside its mailbox.
    pub fn emergency_trigger(&self) -> EmergencyTrigger {
        self.emergencies.clone()
    }

    /// Emergencies waiting for the next poll.
    pub fn pending_emergencies(&self) -> usize {
        self.emergencies.pending()
    }

    /// Emergencies dropped because the queue was full.
    pub fn dropped_emergencies(&self) -> u64 {
        self.emergencies.dropped()
    }

    /// Requests answered with a mailbox error instead of a CoE reply (malformed or a CoE
    /// service the server does not serve).
    pub fn refused(&self) -> u64 {
        self.refused
    }
}

impl MailboxService for CoeService {
    fn mailbox_type(&self) -> MailboxType {
        MailboxType::Coe
    }

    fn handle(
        &mut self,
        _request: &MailboxHeader,
        data: &[u8],
        ctx: &DeviceContext,
        replies: &mut ReplySink,
    ) {
        let server_ctx = ServerContext {
            mailbox_size: usize::from(ctx.tx_mailbox_size),
            rx_mailbox_size: usize::from(ctx.rx_mailbox_size),
            state: ctx.al_state,
        };
        let mut answers: Vec<Vec<u8>> = Vec::new();
        let outcome = if let Some(refusal) = self.quirks.refusal(data) {
            answers.push(refusal);
            Outcome::Replied(1)
        } else {
            let mut dict = lock_dictionary(&self.dict);
            self.server
                .handle(&mut *dict, data, server_ctx, &mut |reply: &[u8]| {
                    answers.push(reply.to_vec())
                })
        };
        let refusal = match outcome {
            Outcome::Replied(_) => None,
            Outcome::Unsupported(_) => Some(MailboxErrorCode::ServiceNotSupported),
            Outcome::Malformed => Some(MailboxErrorCode::InvalidSize),
            // The layer cannot post anything through an SM1 this small either.
            Outcome::MailboxTooSmall => None,
        };
        if let Some(code) = refusal {
            self.refused += 1;
            let _ = replies.mailbox_error(code);
            return;
        }
        // All fragments or none: a master cannot use half an OD list.
        if answers.len() > replies.room() {
            let _ = replies.mailbox_error(MailboxErrorCode::NoMoreMemory);
            return;
        }
        for mut answer in answers {
            self.quirks.apply(data, &mut answer);
            let _ = replies.send(answer);
        }
    }

    fn poll(&mut self, _ctx: &DeviceContext, replies: &mut ReplySink) {
        while replies.room() > 0 {
            let Some(message) = self.emergencies.pop() else {
                break;
            };
            let _ = replies.send(message.to_vec());
        }
    }

    fn reset(&mut self) {
        self.server.reset();
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ecat_wire::coe::{DataType, ObjectAccess};
    use ecat_wire::register::AlState;

    fn ctx() -> DeviceContext {
        DeviceContext {
            station_address: 0x1001,
            al_state: AlState::PreOp,
            rx_mailbox_size: 128,
            tx_mailbox_size: 128,
        }
    }

    fn header() -> MailboxHeader {
        MailboxHeader {
            length: 10,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Coe,
            counter: 1,
        }
    }

    fn service() -> CoeService {
        let dict = StaticDictionary::builder()
            .var(
                0x6040,
                "Controlword",
                DataType::Unsigned16,
                ObjectAccess::RW,
                0u16,
            )
            .build()
            .unwrap();
        CoeService::new(dict)
    }

    #[test]
    fn expedited_download_is_counted_once() {
        let mut coe = service();
        let mut sink = ReplySink::new(MailboxType::Coe, 0, 122, 8);
        // CoE header SDO request (0x2000), initiate download expedited 2 bytes, 0x6040:00.
        let request = [0x00, 0x20, 0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0x00, 0x00];
        coe.handle(&header(), &request, &ctx(), &mut sink);
        assert_eq!(sink.len(), 1);
        assert_eq!(coe.write_count(0x6040), 1);
        let dict = coe.dictionary();
        assert_eq!(
            lock_dictionary(&dict).get::<u16>(0x6040, 0).unwrap(),
            0x000F
        );
    }

    #[test]
    fn emergencies_wait_for_poll() {
        let mut coe = service();
        assert!(coe.raise_emergency(0x8100, 0x11, [1, 2, 3, 4, 5]));
        assert_eq!(coe.pending_emergencies(), 1);
        let mut sink = ReplySink::new(MailboxType::Coe, 0, 122, 8);
        coe.poll(&ctx(), &mut sink);
        assert_eq!(sink.len(), 1);
        assert_eq!(coe.pending_emergencies(), 0);
    }

    #[test]
    fn unsupported_service_gets_a_mailbox_error() {
        let mut coe = service();
        let mut sink = ReplySink::new(MailboxType::Coe, 0, 122, 8);
        // CoE service 1 (emergency) from the master.
        let request = [0x00, 0x10, 0, 0, 0, 0, 0, 0, 0, 0];
        coe.handle(&header(), &request, &ctx(), &mut sink);
        assert_eq!(coe.refused(), 1);
        assert_eq!(sink.len(), 1);
    }

    #[test]
    fn a_trigger_raises_on_the_service_and_its_queue_is_bounded() {
        let coe = CoeService::new(StaticDictionary::default());
        let trigger = coe.emergency_trigger();
        let mut coe = coe;
        for i in 0..EMERGENCY_QUEUE as u16 {
            assert!(trigger.raise(0x8100 + i, 0x11, [0; 5]));
        }
        assert!(!trigger.raise(0x8200, 0x11, [0; 5]), "the queue is full");
        assert_eq!(coe.pending_emergencies(), EMERGENCY_QUEUE);
        assert_eq!(coe.dropped_emergencies(), 1);
        let mut sink = ReplySink::new(MailboxType::Coe, 0, 122, 4);
        coe.poll(&ctx(), &mut sink);
        assert_eq!(sink.len(), 4, "as many as the sink has room for");
        assert_eq!(trigger.pending(), EMERGENCY_QUEUE - 4);
    }
}
