//! The link between one TAP interface and its slave's mailbox: a reader that takes frames
//! from the TAP and hands them to the slave's EoE queue, and a writer that puts the frames
//! the slave sends onto the TAP.
//!
//! Flow control: at most as many frames are handed to the mailbox as its EoE queue holds
//! ([`MailboxConfig::eoe_tx_queue_len`](master_core::mailbox::MailboxConfig)); while that
//! many are on their way the TAP is not read, so frames wait in the kernel's queue (whose
//! overflow the kernel counts) and ecatd's memory never grows. A frame the mailbox could
//! not send is counted as dropped.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use futures_util::StreamExt;
use futures_util::stream::FuturesUnordered;
use master_core::mailbox::{IpSettings, MailboxError, SlaveMailbox};
use tokio::sync::broadcast::error::RecvError;
use tokio::task::JoinHandle;

use super::tap::Tap;
use super::{Counters, add};

/// Room for the largest frame a TAP hands over (1500-byte MTU, Ethernet and VLAN headers).
const FRAME_BUFFER: usize = 1522;

/// Starts the reader and the writer; Set IP (`ip`) goes first, before any frame.
pub(super) fn start(
    tap: Arc<Tap>,
    mailbox: SlaveMailbox,
    ip: Option<IpSettings>,
    queue_len: usize,
    counters: Arc<Counters>,
    stale: Arc<AtomicBool>,
) -> [JoinHandle<()>; 2] {
    // Subscribed before anything is sent, so no answer is missed.
    let frames = mailbox.subscribe_eoe();
    let writer = tokio::spawn(write_frames(
        Arc::clone(&tap),
        frames,
        Arc::clone(&counters),
        Arc::clone(&stale),
    ));
    let reader = tokio::spawn(async move {
        if let Some(ip) = ip {
            match mailbox.eoe_set_ip(&ip).await {
                Ok(()) => tracing::info!(interface = tap.name(), "EoE Set IP sent"),
                Err(err) => tracing::warn!(interface = tap.name(), %err, "EoE Set IP failed"),
            }
        }
        read_frames(&tap, &mailbox, queue_len, &counters, &stale).await;
    });
    [reader, writer]
}

async fn read_frames(
    tap: &Tap,
    mailbox: &SlaveMailbox,
    queue_len: usize,
    counters: &Counters,
    stale: &AtomicBool,
) {
    let mut buf = vec![0u8; FRAME_BUFFER];
    let mut in_flight = FuturesUnordered::new();
    loop {
        tokio::select! {
            read = tap.read(&mut buf), if in_flight.len() < queue_len => match read {
                Ok(0) => {}
                Ok(n) => {
                    let frame = buf[..n].to_vec();
                    let mailbox = mailbox.clone();
                    in_flight.push(async move { (mailbox.eoe_send(&frame).await, frame.len()) });
                }
                Err(err) => {
                    tracing::warn!(interface = tap.name(), %err, "cannot read the interface");
                    return;
                }
            },
            Some((sent, len)) = in_flight.next(), if !in_flight.is_empty() => match sent {
                Ok(()) => {
                    counters.frames_out.fetch_add(1, Ordering::Relaxed);
                    add(&counters.bytes_out, len);
                }
                Err(err) => {
                    counters.drops_out.fetch_add(1, Ordering::Relaxed);
                    if matches!(err, MailboxError::Shutdown) {
                        // The slave's mailbox owner is gone (the slave went through INIT).
                        stale.store(true, Ordering::Relaxed);
                    }
                }
            },
        }
    }
}

async fn write_frames(
    tap: Arc<Tap>,
    mut frames: tokio::sync::broadcast::Receiver<master_core::mailbox::EoeFrame>,
    counters: Arc<Counters>,
    stale: Arc<AtomicBool>,
) {
    loop {
        match frames.recv().await {
            Ok(frame) => match tap.write(&frame.frame).await {
                Ok(()) => {
                    counters.frames_in.fetch_add(1, Ordering::Relaxed);
                    add(&counters.bytes_in, frame.frame.len());
                }
                Err(_) => {
                    counters.drops_in.fetch_add(1, Ordering::Relaxed);
                }
            },
            Err(RecvError::Lagged(n)) => {
                add(&counters.drops_in, usize::try_from(n).unwrap_or(usize::MAX))
            }
            Err(RecvError::Closed) => {
                stale.store(true, Ordering::Relaxed);
                return;
            }
        }
    }
}
