//! The UDP transport (ETG.8200's own): each datagram is one message, checked against the
//! allowlist, admitted by the service and worked on in its own task, so a slow slave never
//! holds up the others. Replies go from the bound socket to the client's address and port.

use std::sync::Arc;

use tokio::net::UdpSocket;
use tokio::task::JoinSet;

use super::service::{Admitted, ReplyTo, Shared, admit, screened, serve};

/// The largest UDP payload; a datagram is read whole, whatever its size, so that an
/// oversized one is seen as such and not cut to something that parses.
const RECEIVE_BUFFER: usize = 65_536;

/// Receives and serves datagrams until dropped (the request tasks go with it).
pub(crate) async fn run(shared: Arc<Shared>, socket: Arc<UdpSocket>) {
    let mut buf = vec![0u8; RECEIVE_BUFFER];
    let mut tasks = JoinSet::new();
    loop {
        let (len, client) = tokio::select! {
            Some(_) = tasks.join_next(), if !tasks.is_empty() => continue,
            received = socket.recv_from(&mut buf) => match received {
                Ok(r) => r,
                // ICMP port unreachable from an earlier reply, and the like: not fatal.
                Err(_) => continue,
            },
        };
        let Some((datagram, received)) = screened(&shared, &buf, len, client) else {
            continue;
        };
        let reply_to = ReplyTo::Udp(Arc::clone(&socket));
        if let Admitted::Serve(request, ticket) =
            admit(&shared, datagram, client, reply_to, received).await
        {
            tasks.spawn(serve(Arc::clone(&shared), request, ticket));
        }
    }
}
