//! Messages a slave sends on its own — CoE emergencies, EoE frames, SoE notifications —
//! and where they go: a bounded history (emergencies) and broadcast channels.

use std::collections::VecDeque;
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::SystemTime;

use tokio::sync::broadcast;

use crate::wire::coe::EmergencyRepr;

use super::stats::{Stats, add, inc};

/// A CoE emergency (ETG.1000.6, spec-notes §coe.emcy) as received.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emergency {
    /// Station address of the slave that sent it.
    pub station: u16,
    /// CiA 301 error code.
    pub error_code: u16,
    /// Error register (object 0x1001).
    pub error_register: u8,
    /// Manufacturer-specific data.
    pub data: [u8; 5],
    /// When the master read it.
    pub received_at: SystemTime,
}

/// An Ethernet frame a slave sent over EoE, reassembled (without FCS).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EoeFrame {
    /// Station address of the slave that sent it.
    pub station: u16,
    /// The Ethernet frame, destination MAC first.
    pub frame: Vec<u8>,
}

/// An SoE notification or slave-info message (opcode 5 or 6, spec-notes §soe), kept raw: the
/// layout after the header is not standardised.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SoeNotification {
    /// Station address of the slave that sent it.
    pub station: u16,
    /// The SoE message (header and data) as received.
    pub message: Vec<u8>,
}

/// The event outlets of one slave.
#[derive(Debug)]
pub(crate) struct Events {
    history: Mutex<VecDeque<Emergency>>,
    history_len: usize,
    pub emergencies: broadcast::Sender<Emergency>,
    pub eoe_frames: broadcast::Sender<EoeFrame>,
    pub soe_notifications: broadcast::Sender<SoeNotification>,
}

impl Events {
    pub fn new(history_len: usize, capacity: usize) -> Events {
        let capacity = capacity.max(1);
        Events {
            history: Mutex::new(VecDeque::with_capacity(history_len)),
            history_len,
            emergencies: broadcast::channel(capacity).0,
            eoe_frames: broadcast::channel(capacity).0,
            soe_notifications: broadcast::channel(capacity).0,
        }
    }

    fn history(&self) -> MutexGuard<'_, VecDeque<Emergency>> {
        // Updates are single push/pop calls: a poisoned lock still holds a valid queue.
        self.history.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The emergencies kept, oldest first.
    pub fn emergencies(&self) -> Vec<Emergency> {
        self.history().iter().copied().collect()
    }

    pub fn emergency(&self, station: u16, repr: &EmergencyRepr, stats: &Stats) {
        inc(&stats.emergencies);
        let emergency = Emergency {
            station,
            error_code: repr.error_code,
            error_register: repr.error_register,
            data: repr.data,
            received_at: SystemTime::now(),
        };
        {
            let mut history = self.history();
            if history.len() >= self.history_len {
                history.pop_front();
            }
            if self.history_len > 0 {
                history.push_back(emergency);
            }
        }
        // Nobody listening is fine: the history keeps it.
        let _ = self.emergencies.send(emergency);
    }

    pub fn eoe_frame(&self, frame: EoeFrame, stats: &Stats) {
        inc(&stats.eoe_frames_in);
        add(&stats.eoe_bytes_in, frame.frame.len());
        if self.eoe_frames.send(frame).is_err() {
            inc(&stats.events_unheard);
        }
    }

    pub fn soe_notification(&self, notification: SoeNotification, stats: &Stats) {
        inc(&stats.soe_notifications);
        if self.soe_notifications.send(notification).is_err() {
            inc(&stats.events_unheard);
        }
    }
}
