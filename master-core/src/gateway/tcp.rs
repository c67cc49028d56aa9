//! The optional TCP transport (ETG.8200 allows it beside UDP): a connection carries a byte
//! stream of gateway messages, each delimited by its EtherCAT header's length (2 bytes of
//! header, then `length` bytes). A connection is a thin layer over the service, as the UDP
//! loop is: its messages go through the same [`admit`] (parsing, counting, in-flight caps, sessions and
//! routing by client address) and [`serve`], one message at a time in the order they
//! arrive, and the replies go back on the connection in that order.
//!
//! Bounds: [`GatewayConfig::max_tcp_connections`](super::GatewayConfig::max_tcp_connections)
//! connections, each closed after
//! [`GatewayConfig::tcp_idle_timeout`](super::GatewayConfig::tcp_idle_timeout) without a
//! whole message (or with a reply it cannot write); a message is at most the largest valid
//! one (2 + 2047 bytes). A header that cannot start a gateway message (type other than 5,
//! reserved bit set, length shorter than a mailbox header) or a message that does not
//! parse closes the connection — the stream cannot be trusted to be in step any more —
//! and counts as `malformed`.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant as StdInstant};

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore, mpsc};
use tokio::task::JoinSet;
use tokio::time::timeout;

use crate::wire::frame::{self, Frame, FrameType};
use crate::wire::mailbox;

use super::service::{Admitted, ReplyTo, Shared, admit, serve};
use super::stats::FailureReason;

/// The largest gateway message: the EtherCAT header and the most its 11-bit length says.
pub(crate) const MAX_MESSAGE: usize = frame::HEADER_LEN + frame::MAX_LENGTH as usize;

/// Replies waiting to be written on one connection (one request's replies at a time;
/// SDO Information and SoE fragments can be several).
const WRITE_QUEUE: usize = 64;

/// Accepts and serves connections until dropped (the connections go with it).
pub(crate) async fn run(shared: Arc<Shared>, listener: TcpListener) {
    let connections = Connections::new(shared.config.max_tcp_connections);
    let mut tasks = JoinSet::new();
    loop {
        tokio::select! {
            Some(_) = tasks.join_next(), if !tasks.is_empty() => {}
            accepted = listener.accept() => {
                if let Ok((stream, peer)) = accepted
                    && let Some(connection) = connections.open(&shared, stream, peer)
                {
                    tasks.spawn(connection);
                }
            }
        }
    }
}

/// The cap on connections served at once.
struct Connections {
    slots: Arc<Semaphore>,
}

impl Connections {
    /// At most `max` connections (at least 1).
    fn new(max: usize) -> Connections {
        Connections {
            slots: Arc::new(Semaphore::new(max.max(1))),
        }
    }

    /// The task serving a new connection from `peer`, or `None` if it is refused (closed
    /// at once): a client not allowed counts as `denied`, one beyond the cap as `busy`.
    fn open(
        &self,
        shared: &Arc<Shared>,
        stream: TcpStream,
        peer: SocketAddr,
    ) -> Option<impl Future<Output = ()> + Send + 'static> {
        if !shared.config.allows(peer.ip()) {
            shared.stats.received();
            // Refused at accept, before any message: nothing was waited for.
            shared.stats.failed(FailureReason::Denied, Duration::ZERO);
            return None;
        }
        let Ok(slot) = Arc::clone(&self.slots).try_acquire_owned() else {
            shared.stats.received();
            shared.stats.failed(FailureReason::Busy, Duration::ZERO);
            return None;
        };
        Some(connection(Arc::clone(shared), stream, peer, slot))
    }
}

/// Why reading a message stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stop {
    /// The client closed, or the connection failed.
    Closed,
    /// The header cannot start a gateway message.
    Malformed,
}

/// Reads one message into `buf` (at least [`MAX_MESSAGE`] bytes); its length, or why
/// there is none.
pub(crate) async fn read_message<R: AsyncRead + Unpin>(
    reader: &mut R,
    buf: &mut [u8],
) -> Result<usize, Stop> {
    let header = buf.get_mut(..frame::HEADER_LEN).ok_or(Stop::Closed)?;
    reader.read_exact(header).await.map_err(|_| Stop::Closed)?;
    let view = Frame::new_unchecked(&*header);
    let length = usize::from(view.length());
    if view.frame_type() != FrameType::Mailbox
        || view.reserved_bit()
        || length < mailbox::HEADER_LEN
    {
        return Err(Stop::Malformed);
    }
    let end = frame::HEADER_LEN + length;
    let body = buf.get_mut(frame::HEADER_LEN..end).ok_or(Stop::Malformed)?;
    reader.read_exact(body).await.map_err(|_| Stop::Closed)?;
    Ok(end)
}

/// Serves one connection until the client closes it, it idles, or it sends garbage.
async fn connection(
    shared: Arc<Shared>,
    stream: TcpStream,
    peer: SocketAddr,
    _slot: OwnedSemaphorePermit,
) {
    // Replies are whole messages written at once: no need to wait for more.
    let _ = stream.set_nodelay(true);
    let idle = shared.config.tcp_idle_timeout;
    let (mut reader, mut writer) = stream.into_split();
    let (replies, mut outgoing) = mpsc::channel::<Vec<u8>>(WRITE_QUEUE);
    let write = async move {
        while let Some(message) = outgoing.recv().await {
            // A client that does not read its replies loses its connection.
            if !matches!(timeout(idle, writer.write_all(&message)).await, Ok(Ok(()))) {
                break;
            }
        }
        // Dropping the write half sends FIN once everything queued is written.
    };
    let read = async move {
        let mut buf = vec![0u8; MAX_MESSAGE];
        loop {
            let len = match timeout(idle, read_message(&mut reader, &mut buf)).await {
                Ok(Ok(len)) => len,
                Ok(Err(Stop::Malformed)) => {
                    shared.stats.received();
                    // A header that cannot start a message: refused as it is read.
                    shared
                        .stats
                        .failed(FailureReason::Malformed, Duration::ZERO);
                    break;
                }
                Ok(Err(Stop::Closed)) | Err(_) => break,
            };
            let received = StdInstant::now();
            shared.stats.received();
            let Some(message) = buf.get(..len) else {
                break;
            };
            let reply_to = ReplyTo::Tcp(replies.clone());
            match admit(&shared, message, peer, reply_to, received).await {
                // One at a time: the replies go back in the order of the requests.
                Admitted::Serve(request, ticket) => {
                    serve(Arc::clone(&shared), request, ticket).await;
                }
                Admitted::Done => {}
                Admitted::Malformed => break,
            }
        }
        // The last sender goes: the writer finishes what is queued and closes.
        drop(replies);
    };
    tokio::join!(read, write);
}
