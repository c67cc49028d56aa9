//! [`MasterDictionary`]: serves CoE requests against the master's dictionary with the same
//! SDO server the simulated slaves use, one server per client (each client's segmented
//! transfer has its own state).
//!
//! Values are live: each request takes a [`MasterSnapshot`] and builds the dictionary from
//! it (a few dozen objects per slave, cheap next to a mailbox round trip). Values that cost
//! a bus access are fetched only for the object a request names: the ESC error counters
//! for an upload of 0xAnnn, the SII order code for 0x8nnn; other requests show the last
//! counters read. A segmented upload sends the value as it was at its initiate.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use crate::master::{Master, SlaveAddress};
use crate::od::{MIN_MAILBOX_SIZE, Outcome, SdoServer, ServerContext};
use crate::wire::coe::{AbortCode, CoeFrame, CoeService, SdoFrame};
use crate::wire::mailbox::{MailboxErrorCode, MailboxType};
use crate::wire::register::address::ERROR_COUNTERS;
use crate::wire::register::error_counters::ERROR_COUNTERS_LEN;
use crate::wire::register::{AlState, ErrorCounters, ErrorCountersRepr};
use crate::wire::sii::SiiImage;

use super::diagnosis::{Diagnosis, track};
use super::dictionary::{Action, Actions, build};
use super::identity::MasterIdentity;
use super::slaves::{CONFIGURATION, DIAGNOSIS};
use super::snapshot::{MasterSnapshot, ScanStatus};

/// Clients whose SDO state is kept at once; the one silent longest makes room.
const MAX_CLIENTS: usize = 64;

/// SDO command specifiers that start a transfer (download 1, upload 2).
const INITIATE_DOWNLOAD: u8 = 1;
const INITIATE_UPLOAD: u8 = 2;

/// One reply message: its mailbox type and data.
pub type Reply = (MailboxType, Vec<u8>);

/// The master's ETG.1510 dictionary as a CoE server: values built per request from the
/// live master, one SDO server state per client (see [`crate::master_od`]).
#[derive(Debug)]
pub struct MasterDictionary {
    master: Arc<Master>,
    identity: MasterIdentity,
    mailbox_size: usize,
    diagnosis: Arc<Diagnosis>,
    clients: Mutex<HashMap<SocketAddr, (SdoServer, Instant)>>,
    counters: Mutex<HashMap<u16, ErrorCountersRepr>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The object a request starts a transfer of (SDO initiate upload or download).
fn named_object(request: &[u8]) -> Option<u16> {
    let coe = CoeFrame::new_checked(request).ok()?;
    if coe.service() != CoeService::SdoRequest {
        return None;
    }
    let frame = SdoFrame::new_checked(request).ok()?;
    matches!(frame.specifier(), INITIATE_DOWNLOAD | INITIATE_UPLOAD).then(|| frame.index())
}

/// The AL state in the low nibble of an AL control value.
fn requested(control: u16) -> AlState {
    AlState::from((control & 0x0F) as u8)
}

impl MasterDictionary {
    /// The dictionary of `master`, answering through a mailbox of `mailbox_size` bytes
    /// (header included, at least 16): longer values are transferred segmented.
    pub fn new(master: Arc<Master>, identity: MasterIdentity, mailbox_size: usize) -> Self {
        MasterDictionary {
            master,
            identity,
            mailbox_size: mailbox_size.max(MIN_MAILBOX_SIZE),
            diagnosis: Arc::default(),
            clients: Mutex::new(HashMap::new()),
            counters: Mutex::new(HashMap::new()),
        }
    }

    /// The task that keeps the not-present and abnormal-state counters and the frame
    /// rates; spawn it on any runtime for as long as the dictionary is served.
    pub fn tracker(&self) -> impl Future<Output = ()> + Send + 'static {
        track(Arc::clone(&self.diagnosis), Arc::clone(&self.master))
    }

    /// The values the dictionary shows now; `focus` is the object whose costly values
    /// (error counters, order code) are fetched from the segment.
    pub async fn snapshot(&self, focus: Option<u16>) -> MasterSnapshot {
        let slaves = self.master.slaves();
        let mut snap = MasterSnapshot {
            diagnosis: self.diagnosis.slaves(),
            rates: self.diagnosis.rates(),
            scan: self.diagnosis.scan(),
            ..MasterSnapshot::default()
        };
        let count = slaves.len() as u16;
        match focus {
            Some(index) if (CONFIGURATION..CONFIGURATION + count).contains(&index) => {
                let position = index - CONFIGURATION;
                if let Ok(sii) = self.master.sii_image(SlaveAddress::Position(position))
                    && let Some(order) = SiiImage::parse(&sii).ok().and_then(|s| s.order())
                {
                    snap.order_codes.insert(position, order.to_owned());
                }
            }
            Some(index) if (DIAGNOSIS..DIAGNOSIS + count).contains(&index) => {
                let position = index - DIAGNOSIS;
                let read = self
                    .master
                    .read_register(
                        SlaveAddress::Position(position),
                        ERROR_COUNTERS,
                        ERROR_COUNTERS_LEN,
                    )
                    .await;
                if let Some(repr) = read.ok().and_then(|bytes| {
                    ErrorCounters::new_checked(&bytes[..])
                        .and_then(|v| ErrorCountersRepr::parse(&v))
                        .ok()
                }) {
                    lock(&self.counters).insert(position, repr);
                }
            }
            _ => {}
        }
        snap.error_counters = lock(&self.counters).clone();
        let bus = self.master.bus().stats();
        snap.cyclic_lost = bus.cycles_lost;
        snap.acyclic_lost = bus.frames_lost.saturating_sub(bus.cycles_lost);
        snap.wkc_errors = self.master.wkc_errors();
        snap.slaves = slaves;
        snap
    }

    /// Serves one CoE request (mailbox data) from `client`; returns the replies in order
    /// (SDO responses, SDO Information fragments, or a mailbox error for a request that is
    /// not an SDO or SDO Information request). A download that asks for an action (AL
    /// control, scan, diagnosis reset) is answered once the action is done or under way.
    pub async fn handle(&self, client: SocketAddr, request: &[u8]) -> Vec<Reply> {
        let focus = named_object(request);
        let snap = self.snapshot(focus).await;
        let actions = Actions::default();
        let Ok(mut dict) = build(&snap, &self.identity, &actions) else {
            let (index, subindex) = SdoFrame::new_checked(request)
                .map(|f| (f.index(), f.subindex()))
                .unwrap_or((0, 0));
            let abort = crate::gateway::sdo_abort(index, subindex, AbortCode::GeneralError);
            return vec![(MailboxType::Coe, abort)];
        };
        let ctx = ServerContext {
            mailbox_size: self.mailbox_size,
            rx_mailbox_size: 0,
            state: AlState::Op,
        };
        let mut replies: Vec<Reply> = Vec::new();
        let outcome = {
            let mut clients = lock(&self.clients);
            if !clients.contains_key(&client) && clients.len() >= MAX_CLIENTS {
                let oldest = clients
                    .iter()
                    .min_by_key(|(_, (_, at))| *at)
                    .map(|(k, _)| *k);
                if let Some(oldest) = oldest {
                    clients.remove(&oldest);
                }
            }
            let (server, at) = clients
                .entry(client)
                .or_insert_with(|| (SdoServer::new(), Instant::now()));
            *at = Instant::now();
            server.handle(&mut dict, request, ctx, &mut |reply: &[u8]| {
                replies.push((MailboxType::Coe, reply.to_vec()))
            })
        };
        match outcome {
            Outcome::Replied(_) => {}
            Outcome::Unsupported(_) => {
                return vec![crate::gateway::mailbox_error(
                    MailboxErrorCode::ServiceNotSupported,
                )];
            }
            Outcome::Malformed | Outcome::MailboxTooSmall => {
                return vec![crate::gateway::mailbox_error(
                    MailboxErrorCode::SizeTooShort,
                )];
            }
        }
        let pending: Vec<Action> = std::mem::take(&mut *lock(&actions));
        for action in pending {
            if let Err(code) = self.act(action).await {
                let (index, subindex) = SdoFrame::new_checked(request)
                    .map(|f| (f.index(), f.subindex()))
                    .unwrap_or((0, 0));
                let abort = crate::gateway::sdo_abort(index, subindex, code);
                return vec![(MailboxType::Coe, abort)];
            }
        }
        replies
    }

    /// Carries out an action; the abort code to answer with if it failed.
    async fn act(&self, action: Action) -> Result<(), AbortCode> {
        match action {
            Action::RequestState { position, control } => self
                .master
                .request_state(SlaveAddress::Position(position), requested(control))
                .await
                .map_err(|_| AbortCode::TransferFailed),
            Action::Scan => {
                if self.diagnosis.scan().status == ScanStatus::RUNNING {
                    return Err(AbortCode::DeviceState);
                }
                self.diagnosis.set_scan(ScanStatus {
                    status: ScanStatus::RUNNING,
                    ..ScanStatus::default()
                });
                let master = Arc::clone(&self.master);
                let diagnosis = Arc::clone(&self.diagnosis);
                // The scan takes seconds; the client polls 0xF002:02 for its end.
                tokio::spawn(async move {
                    let status = match master.scan().await {
                        Ok(report) => ScanStatus {
                            status: ScanStatus::DONE,
                            found: report.slaves.len() as u16,
                            failures: report.failures.len() as u16,
                        },
                        Err(_) => ScanStatus {
                            status: ScanStatus::FAILED,
                            ..ScanStatus::default()
                        },
                    };
                    diagnosis.set_scan(status);
                });
                Ok(())
            }
            Action::ResetDiagnosis => {
                self.diagnosis.reset();
                lock(&self.counters).clear();
                // Any write clears the ESC's error counters (ETG.1000.4, spec-notes §esc.errors).
                let zeros = [0u8; ERROR_COUNTERS_LEN];
                for slave in self.master.slaves().iter().filter(|s| s.present) {
                    let _ = self
                        .master
                        .write_register(
                            SlaveAddress::Position(slave.position),
                            ERROR_COUNTERS,
                            &zeros,
                        )
                        .await;
                }
                Ok(())
            }
        }
    }

    /// Forgets the SDO state of every client.
    pub fn reset_clients(&self) {
        lock(&self.clients).clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_named_object_is_that_of_an_initiate() {
        assert_eq!(
            named_object(&[0x00, 0x20, 0x40, 0x05, 0xA0, 0x01, 0, 0, 0, 0]),
            Some(0xA005)
        );
        assert_eq!(named_object(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]), None);
        assert_eq!(named_object(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00]), None);
        assert_eq!(requested(0x0012), AlState::PreOp);
    }
}
