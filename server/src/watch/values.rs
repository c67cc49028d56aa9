//! The last value and the error count of every watch, which `crate::metrics::watch`
//! exports at scrape time as `ecat_watch_value` and `ecat_watch_read_errors_total`.

use std::sync::{Mutex, MutexGuard, PoisonError};

/// The labels of one watch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WatchLabels {
    /// The slave as configured.
    pub slave: String,
    /// `0x6041:00` or `S-0-0051`.
    pub object: String,
    /// The configured name (may be empty).
    pub name: String,
}

/// One watch as [`WatchValues::samples`] reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct WatchSample {
    /// Its labels.
    pub labels: WatchLabels,
    /// The last value read, if one ever was.
    pub value: Option<f64>,
    /// Failed reads.
    pub errors: u64,
}

#[derive(Debug, Clone)]
struct Slot {
    labels: WatchLabels,
    value: Option<f64>,
    errors: u64,
    /// A process-data entry (index, subindex), read from the image at scrape time.
    pdo: Option<(u16, u8)>,
}

/// Every watch's state, by its place in the configuration.
#[derive(Debug, Default)]
pub struct WatchValues {
    slots: Mutex<Vec<Slot>>,
}

impl WatchValues {
    fn lock(&self) -> MutexGuard<'_, Vec<Slot>> {
        // Updates are single assignments: a poisoned lock still holds valid values.
        self.slots.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Adds a watch without a value yet; returns its slot.
    pub fn add(&self, labels: WatchLabels) -> usize {
        let mut slots = self.lock();
        slots.push(Slot {
            labels,
            value: None,
            errors: 0,
            pdo: None,
        });
        slots.len() - 1
    }

    /// Adds a watch of the process-data entry `index:subindex`, read at scrape time.
    pub fn add_pdo(&self, labels: WatchLabels, index: u16, subindex: u8) {
        self.lock().push(Slot {
            labels,
            value: None,
            errors: 0,
            pdo: Some((index, subindex)),
        });
    }

    /// Sets every process-data watch from `read` (slave, index, subindex → the value in the
    /// last cycle, or `None` when the entry is not mapped: an error counted).
    pub fn refresh_pdo(&self, mut read: impl FnMut(&str, u16, u8) -> Option<f64>) {
        for slot in self.lock().iter_mut() {
            if let Some((index, subindex)) = slot.pdo {
                match read(&slot.labels.slave, index, subindex) {
                    Some(value) => slot.value = Some(value),
                    None => slot.errors += 1,
                }
            }
        }
    }

    /// Records a value read.
    pub fn set(&self, slot: usize, value: f64) {
        if let Some(slot) = self.lock().get_mut(slot) {
            slot.value = Some(value);
        }
    }

    /// Records a failed read (the last value stays).
    pub fn fail(&self, slot: usize) {
        if let Some(slot) = self.lock().get_mut(slot) {
            slot.errors += 1;
        }
    }

    /// Every watch's labels, last value (`None`: never read successfully) and error count,
    /// in configuration order.
    pub fn samples(&self) -> Vec<WatchSample> {
        self.lock()
            .iter()
            .map(|slot| WatchSample {
                labels: slot.labels.clone(),
                value: slot.value,
                errors: slot.errors,
            })
            .collect()
    }
}
