//! Sending Ethernet frames over EoE: one fragment per turn of the owner task, so a request
//! that arrives meanwhile goes first (EoE uses the mailbox only when nothing else waits).

use std::time::Instant;

use tokio::sync::{mpsc, oneshot};

use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::hook::Background;
use crate::mailbox::engine::job::BoxFuture;
use crate::mailbox::engine::stats::{add, inc};
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::Emit;
use crate::wire::eoe::{EoeRepr, Fragmenter};
use crate::wire::mailbox::MailboxType;

/// A frame queued for sending, and who to tell when it is out.
pub(crate) struct EoeSend {
    pub frame: Vec<u8>,
    pub port: u8,
    pub done: oneshot::Sender<Result<()>>,
}

/// The queue of frames to send, the frame being sent and the EoE frame number (4 bits,
/// per slave).
pub(crate) struct EoeTx {
    queue: mpsc::Receiver<EoeSend>,
    current: Option<(EoeSend, usize)>,
    frame_number: u8,
}

impl EoeTx {
    /// A sender taking its frames from `queue`, starting at frame number 0.
    pub fn new(queue: mpsc::Receiver<EoeSend>) -> EoeTx {
        EoeTx {
            queue,
            current: None,
            frame_number: 0,
        }
    }

    /// Whether a frame is being sent.
    pub fn busy(&self) -> bool {
        self.current.is_some()
    }

    /// Starts sending `send`.
    pub fn start(&mut self, send: EoeSend) {
        self.current = Some((send, 0));
    }

    /// Writes the next fragment of the current frame.
    pub async fn step(&mut self, exchange: &mut Exchange) {
        let Some((send, index)) = self.current.take() else {
            return;
        };
        let deadline = Instant::now() + exchange.config().timeout;
        exchange.begin(deadline, None, None);
        let size = exchange.write_size();
        let fragment = Fragmenter::new(&send.frame, size, self.frame_number)
            .map(|f| f.with_port(send.port).nth(index));
        let result = match fragment {
            Err(err) => Err(MailboxError::Invalid(err)),
            Ok(None) => Err(exchange.violation("no fragment left")),
            Ok(Some(fragment)) => {
                let last = fragment.last;
                let repr = EoeRepr::Fragment(fragment);
                let sent = exchange
                    .send(MailboxType::Eoe, |buf| repr.emit_into(buf))
                    .await;
                match sent {
                    Ok(()) if !last => {
                        exchange.end().await;
                        self.current = Some((send, index + 1));
                        return;
                    }
                    other => other,
                }
            }
        };
        exchange.end().await;
        self.frame_number = (self.frame_number + 1) % 16;
        if result.is_ok() {
            inc(&exchange.stats().eoe_frames_out);
            add(&exchange.stats().eoe_bytes_out, send.frame.len());
        }
        let _ = send.done.send(result);
    }
}

/// The owner task drives EoE sending through the engine's hook.
impl Background for EoeTx {
    fn busy(&self) -> bool {
        EoeTx::busy(self)
    }

    fn try_start(&mut self) {
        if let Ok(send) = self.queue.try_recv() {
            self.start(send);
        }
    }

    fn start_next(&mut self) -> BoxFuture<'_, ()> {
        // Cancel-safe: a frame is taken from the queue only when `recv` completes.
        Box::pin(async move {
            if let Some(send) = self.queue.recv().await {
                self.start(send);
            }
        })
    }

    fn step<'a>(&'a mut self, exchange: &'a mut Exchange) -> BoxFuture<'a, ()> {
        Box::pin(EoeTx::step(self, exchange))
    }

    fn close(&mut self) {
        self.queue.close();
    }
}
