//! Transfers through the API (FoE files, SDO values): their deadlines and their progress.
//!
//! Deadlines follow the transfer: each exchange with the slave gets the mailbox's own
//! timeout, and the window starts again whenever the transfer moves on (an FoE ACK, DATA
//! or BUSY, an SDO segment), so a file of any size finishes as long as the slave keeps
//! answering; a cap derived from the size ([`cap`]) bounds the whole transfer. A caller that
//! goes away (the connection closed) drops the call, and the engine ends the transfer
//! towards the slave with an FoE ERROR or an SDO abort, leaving its mailbox ready.
//!
//! Progress of FoE transfers goes to the event stream as `foe_progress` events (SSE on
//! `/api/v1/events`, gRPC `WatchEvents`), and to the caller's own listener (gRPC `Read`
//! and `WriteWithProgress` stream it back).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use master_core::mailbox::{FoeProgress, SlaveMailbox};

use super::history::EventLog;
use super::view::{EventView, TransferView};

/// The slowest a transfer may be on average before its cap ends it: 4 KiB/s, a tenth of
/// what the smallest usual mailbox (128 bytes) carries at one exchange per millisecond.
pub const MIN_RATE: u64 = 4 << 10;
/// What the cap gives any transfer on top of its size's share (start-up, BUSY phases).
pub const CAP_BASE: Duration = Duration::from_secs(30);
/// The size the cap of a read assumes (the file's size is not known in advance): the
/// mailbox engine's largest file by default.
pub const READ_CAP_SIZE: usize = 64 << 20;
/// The shortest time between two progress events of one transfer.
pub const PROGRESS_PERIOD: Duration = Duration::from_millis(200);

/// The cap on a whole transfer of `size` bytes: [`CAP_BASE`] plus the size at [`MIN_RATE`].
pub fn cap(size: usize) -> Duration {
    CAP_BASE + Duration::from_secs((size as u64).div_ceil(MIN_RATE))
}

/// `mailbox` with deadlines that follow the progress of a transfer of `size` bytes: each
/// exchange gets the handle's own timeout, the whole transfer at most [`cap`].
pub fn with_progress_deadlines(mailbox: &SlaveMailbox, size: usize) -> SlaveMailbox {
    mailbox.with_progress_deadlines(mailbox.timeout(), cap(size))
}

/// A listener for an FoE transfer's progress (called on the mailbox engine's thread).
pub type ProgressFn = Arc<dyn Fn(FoeProgress) + Send + Sync>;

/// Numbers the transfers.
static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// The progress reporter of one FoE transfer: publishes `foe_progress` events (at most every
/// [`PROGRESS_PERIOD`], and the last one always) and passes every report on to `also`.
pub fn reporter(
    events: Option<Arc<EventLog>>,
    (position, station): (u16, u16),
    file: &str,
    write_size: Option<usize>,
    also: Option<ProgressFn>,
) -> ProgressFn {
    let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
    let file = file.to_owned();
    let direction = if write_size.is_some() {
        "write"
    } else {
        "read"
    };
    // When the last event went out; `None` before the first.
    let last: Mutex<Option<Instant>> = Mutex::new(None);
    Arc::new(move |progress: FoeProgress| {
        if let Some(also) = &also {
            also(progress.clone());
        }
        let (Some(events), FoeProgress::Transferred { bytes, total }) = (&events, progress) else {
            return;
        };
        // A write's total is known from the start, a read's only once it is complete (the
        // service layer reports it then).
        let done = total.is_some_and(|t| bytes >= t);
        {
            let now = Instant::now();
            let mut last = last.lock().unwrap_or_else(PoisonError::into_inner);
            if !done && last.is_some_and(|at| now.duration_since(at) < PROGRESS_PERIOD) {
                return;
            }
            *last = Some(now);
        }
        let text = match total {
            Some(total) => format!("FoE {direction} {file}: {bytes} of {total} bytes"),
            None => format!("FoE {direction} {file}: {bytes} bytes"),
        };
        let transfer = TransferView {
            id,
            file: file.clone(),
            direction: direction.into(),
            bytes: bytes as u64,
            total: total.map(|t| t as u64),
            done,
        };
        events.publish(EventView::foe_progress(position, station, text, transfer));
    })
}

/// Logs a transfer that failed, at `info` with who started it: an operator looks for a broken
/// firmware download in the log and asks who ran it. The caller is the one the transport
/// noted ([`crate::audit::caller`]); a program embedding the core has none.
pub fn log_failure(direction: &str, slave: super::SlaveName, file: &str, err: &super::ApiError) {
    let caller = crate::audit::caller();
    tracing::info!(
        caller = caller.as_ref().map(|c| c.caller.as_str()),
        operation = caller.as_ref().map(|c| c.operation.as_str()),
        slave = %slave,
        file,
        direction,
        reason = err.reason(),
        error = %err.message,
        "transfer failed"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cap_grows_with_the_size() {
        assert_eq!(cap(0), CAP_BASE);
        assert_eq!(cap(8 << 20), CAP_BASE + Duration::from_secs(2048));
        assert!(cap(READ_CAP_SIZE) > cap(8 << 20));
    }

    #[test]
    fn events_are_spaced_and_the_last_one_always_goes_out() {
        let (tx, mut rx) = tokio::sync::broadcast::channel(16);
        let log = Arc::new(EventLog::new(16, tx));
        let seen = Arc::new(AtomicU64::new(0));
        let count = Arc::clone(&seen);
        let report = reporter(
            Some(Arc::clone(&log)),
            (0, 0x1001),
            "fw.bin",
            Some(300),
            Some(Arc::new(move |_| {
                count.fetch_add(1, Ordering::Relaxed);
            })),
        );
        for bytes in [0, 100, 200, 300] {
            report(FoeProgress::Transferred {
                bytes,
                total: Some(300),
            });
        }
        // The caller's own listener hears every report.
        assert_eq!(seen.load(Ordering::Relaxed), 4);
        // The stream: the first, then (within the period) only the last.
        let first = rx.try_recv().unwrap().transfer.unwrap();
        assert_eq!(
            (first.bytes, first.total, first.done),
            (0, Some(300), false)
        );
        let last = rx.try_recv().unwrap();
        assert_eq!(last.kind, "foe_progress");
        assert_eq!(last.station, 0x1001);
        let last = last.transfer.unwrap();
        assert_eq!((last.bytes, last.done, last.id), (300, true, first.id));
        assert_eq!(last.direction, "write");
        assert!(rx.try_recv().is_err());
        // Progress is live only: not kept in the history.
        assert!(
            log.query(&crate::service::history::EventFilter::default())
                .is_empty()
        );
    }
}
