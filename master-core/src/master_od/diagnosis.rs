//! The counters behind 0xAnnn:0F/10 and 0xF120:03/04, kept by a task that follows the
//! master's events and samples the bus once a second while the dictionary is served.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use tokio::sync::broadcast::error::RecvError;

use crate::master::{Master, MasterEvent};
use crate::wire::register::AlState;

use super::snapshot::{FrameRates, ScanStatus, SlaveDiagnosis};

#[derive(Debug, Default)]
struct Inner {
    slaves: HashMap<u16, SlaveDiagnosis>,
    rates: FrameRates,
    scan: ScanStatus,
}

/// Shared between the tracking task and the dictionary.
#[derive(Debug, Default)]
pub(crate) struct Diagnosis {
    inner: Mutex<Inner>,
}

impl Diagnosis {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub fn slaves(&self) -> HashMap<u16, SlaveDiagnosis> {
        self.lock().slaves.clone()
    }

    pub fn rates(&self) -> FrameRates {
        self.lock().rates
    }

    pub fn scan(&self) -> ScanStatus {
        self.lock().scan
    }

    pub fn set_scan(&self, scan: ScanStatus) {
        self.lock().scan = scan;
    }

    /// Zeroes the per-slave counters (0xF200:10).
    pub fn reset(&self) {
        self.lock().slaves.clear();
    }

    fn count(&self, event: &MasterEvent, master: &Master) {
        let mut inner = self.lock();
        match event {
            MasterEvent::SlaveLost { position, .. } => {
                let d = inner.slaves.entry(*position).or_default();
                d.not_present = d.not_present.saturating_add(1);
            }
            MasterEvent::AlError { position, .. } => {
                let d = inner.slaves.entry(*position).or_default();
                d.abnormal_state_changes = d.abnormal_state_changes.saturating_add(1);
            }
            MasterEvent::StateChanged { position, to, .. } => {
                // A change away from the state the master keeps the slave in, that the
                // master did not make on its way there, is abnormal.
                let requested = master
                    .slave(crate::master::SlaveAddress::Position(*position))
                    .map(|s| s.requested_state)
                    .unwrap_or(*to);
                let on_the_way = matches!(
                    (requested, *to),
                    (_, AlState::Init | AlState::PreOp | AlState::SafeOp) if rank(*to) <= rank(requested)
                );
                if *to != requested && !on_the_way {
                    let d = inner.slaves.entry(*position).or_default();
                    d.abnormal_state_changes = d.abnormal_state_changes.saturating_add(1);
                }
            }
            _ => {}
        }
    }
}

fn rank(s: AlState) -> u8 {
    match s {
        AlState::Init | AlState::Boot | AlState::Unknown(_) => 0,
        AlState::PreOp => 1,
        AlState::SafeOp => 2,
        AlState::Op => 3,
    }
}

/// Follows `master`'s events and samples the frame rates until the task is dropped.
pub(crate) async fn track(diagnosis: Arc<Diagnosis>, master: Arc<Master>) {
    let mut events = master.events();
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last = master.bus().stats();
    loop {
        tokio::select! {
            event = events.recv() => match event {
                Ok(event) => diagnosis.count(&event, &master),
                Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => return,
            },
            _ = tick.tick() => {
                let now = master.bus().stats();
                let cyclic = now.cycles_run.saturating_sub(last.cycles_run);
                let all = now.frames_sent.saturating_sub(last.frames_sent);
                diagnosis.lock().rates = FrameRates {
                    cyclic: u32::try_from(cyclic).unwrap_or(u32::MAX),
                    acyclic: u32::try_from(all.saturating_sub(cyclic)).unwrap_or(u32::MAX),
                };
                last = now;
            }
        }
    }
}
