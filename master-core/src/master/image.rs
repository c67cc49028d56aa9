//! The process image and the cyclic task that exchanges it with one LRW per cycle.
//!
//! The image is one logical address space starting at 0: every slave's outputs, then its
//! inputs, in ring order. The task runs on the bus thread; callers read and write the image
//! through the master. The lock is held only to copy bytes.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use crate::bus::{CyclicFrame, CyclicReply, CyclicTask};
use crate::wire::command::{Command, DatagramAddress};

/// Logical address of the first image byte.
pub(crate) const LOGICAL_BASE: u32 = 0;

/// Counters of the cyclic exchange.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CycleStats {
    /// Cycles whose frame came back.
    pub completed: u64,
    /// Cycles whose frame was lost.
    pub lost: u64,
    /// Working counter of the last returned LRW.
    pub last_wkc: u16,
    /// Working counter the LRW should have (2 per slave with outputs, 1 per slave with
    /// inputs).
    pub expected_wkc: u16,
    /// Image size in bytes.
    pub image_len: usize,
}

#[derive(Debug, Default)]
struct Buffers {
    /// What is sent: the outputs (input ranges are sent as whatever they hold).
    outputs: Vec<u8>,
    /// What came back last.
    inputs: Vec<u8>,
    expected_wkc: u16,
    last_wkc: u16,
}

/// The image shared by the cyclic task and the master.
#[derive(Debug, Default)]
pub(crate) struct Image {
    buffers: Mutex<Buffers>,
    completed: AtomicU64,
    lost: AtomicU64,
}

impl Image {
    fn lock(&self) -> MutexGuard<'_, Buffers> {
        self.buffers.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Sets the image size and the working counter to expect; keeps the bytes that fit.
    pub fn resize(&self, len: usize, expected_wkc: u16) {
        let mut b = self.lock();
        b.outputs.resize(len, 0);
        b.inputs.resize(len, 0);
        b.expected_wkc = expected_wkc;
    }

    /// Writes `data` into the image at `offset`; false if it does not fit.
    pub fn write(&self, offset: usize, data: &[u8]) -> bool {
        let mut b = self.lock();
        let range = offset..offset.saturating_add(data.len());
        match b.outputs.get_mut(range) {
            Some(target) => {
                target.copy_from_slice(data);
                true
            }
            None => false,
        }
    }

    /// `len` bytes at `offset` of what was sent (`outputs`) or received last.
    pub fn read(&self, offset: usize, len: usize, outputs: bool) -> Option<Vec<u8>> {
        let b = self.lock();
        let source = if outputs { &b.outputs } else { &b.inputs };
        source
            .get(offset..offset.saturating_add(len))
            .map(<[u8]>::to_vec)
    }

    pub fn stats(&self) -> CycleStats {
        let b = self.lock();
        CycleStats {
            completed: self.completed.load(Ordering::Relaxed),
            lost: self.lost.load(Ordering::Relaxed),
            last_wkc: b.last_wkc,
            expected_wkc: b.expected_wkc,
            image_len: b.outputs.len(),
        }
    }

    /// Cycles completed so far.
    pub fn completed(&self) -> u64 {
        self.completed.load(Ordering::Relaxed)
    }
}

/// The bus's cyclic task: one LRW of the whole image per period.
pub(crate) struct ProcessCycle {
    pub image: Arc<Image>,
    pub period: Duration,
}

impl CyclicTask for ProcessCycle {
    fn period(&self) -> Duration {
        self.period
    }

    fn build(&mut self, frame: &mut CyclicFrame<'_>) {
        let b = self.image.lock();
        if b.outputs.is_empty() {
            return;
        }
        // A failure leaves the frame empty: the cycle is skipped, and the image size was
        // checked against the frame when the layout was made.
        let _ = frame.push(
            Command::Lrw,
            DatagramAddress::Logical(LOGICAL_BASE),
            &b.outputs,
        );
    }

    fn complete(&mut self, reply: &CyclicReply<'_>) {
        if let Some(datagram) = reply.datagram(0) {
            let mut b = self.image.lock();
            if datagram.data.len() == b.inputs.len() {
                b.inputs.copy_from_slice(datagram.data);
            }
            b.last_wkc = datagram.wkc;
        }
        self.image.completed.fetch_add(1, Ordering::Relaxed);
    }

    fn lost(&mut self) {
        self.image.lost.fetch_add(1, Ordering::Relaxed);
    }
}
