//! The service loop: receive a datagram, check who sent it and what it is, admit it, and
//! work on it in its own task so a slow slave never holds up the others. TCP connections
//! (`tcp`) hand their messages to the same [`admit`] and [`serve`]; only where the replies
//! go differs ([`ReplyTo`]).

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Instant as StdInstant;

use tokio::net::{TcpListener, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::master::Master;
use crate::master_od::MasterDictionary;
use crate::wire::gateway::{GatewayMessage, GatewayRepr};
use crate::wire::mailbox::{MailboxErrorCode, MailboxHeader, MailboxType};

use super::admission::{Admission, Ticket};
use super::answer::{Fault, answer, mailbox_error};
use super::config::GatewayConfig;
use super::forward::{Forward, forward};
use super::normalize;
use super::reply;
use super::route::{self, Target};
use super::session::Sessions;
use super::stats::{FailureReason, Stats};
use super::tcp;

/// The largest UDP payload; a datagram is read whole, whatever its size, so that an
/// oversized one is seen as such and not cut to something that parses.
const RECEIVE_BUFFER: usize = 65_536;

/// What every request task shares.
pub(crate) struct Shared {
    pub master: Arc<Master>,
    pub config: GatewayConfig,
    pub stats: Arc<Stats>,
    pub sessions: Sessions,
    pub admission: Arc<Admission>,
    pub dictionary: MasterDictionary,
    pub socket: UdpSocket,
}

/// Where the replies to a request go.
#[derive(Debug, Clone)]
pub(crate) enum ReplyTo {
    /// A datagram from the bound socket to the client's address and port.
    Udp,
    /// The writer of the client's TCP connection, in order.
    Tcp(mpsc::Sender<Vec<u8>>),
}

/// One request: who sent it, its header, its (normalised) data, where replies go.
pub(crate) struct Request {
    client: SocketAddr,
    header: MailboxHeader,
    data: Vec<u8>,
    received: StdInstant,
    reply_to: ReplyTo,
}

/// What became of a received message.
pub(crate) enum Admitted {
    /// To be served.
    Serve(Request, Ticket),
    /// Answered or dropped already (busy), counted.
    Done,
    /// Not a gateway message; counted.
    Malformed,
}

/// Parses a received message and admits it; counts what it is. The caller counted it as
/// received and checked the client against the allowlist.
pub(crate) async fn admit(
    shared: &Shared,
    message: &[u8],
    client: SocketAddr,
    reply_to: ReplyTo,
    received: StdInstant,
) -> Admitted {
    let Some(request) = parse(message, client, received, reply_to) else {
        shared.stats.failed(FailureReason::Malformed);
        return Admitted::Malformed;
    };
    shared.stats.parsed(request.header.mailbox_type);
    match shared.admission.admit(client) {
        Some(ticket) => Admitted::Serve(request, ticket),
        None => {
            shared.fail(&request, Fault::Busy).await;
            Admitted::Done
        }
    }
}

impl Shared {
    async fn send(&self, request: &Request, datagram: Vec<u8>) {
        match &request.reply_to {
            // A client that went away is its own problem; UDP has no one to tell.
            ReplyTo::Udp => {
                let _ = self.socket.send_to(&datagram, request.client).await;
            }
            // A closed connection drops its writer: nothing left to send to.
            ReplyTo::Tcp(writer) => {
                let _ = writer.send(datagram).await;
            }
        }
    }

    /// Answers a failed request as the error table says (unless strict) and counts it.
    async fn fail(&self, request: &Request, fault: Fault) {
        self.stats.failed(fault.reason());
        if self.config.strict {
            return;
        }
        let answer = if request.header.address == route::MASTER_ADDRESS
            && request.header.mailbox_type != MailboxType::Coe
            && fault == Fault::Unsupported
        {
            Some(mailbox_error(MailboxErrorCode::UnsupportedProtocol))
        } else {
            answer(request.header.mailbox_type, &request.data, fault)
        };
        if let Some((ty, data)) = answer
            && let Some(datagram) =
                reply::made(request.header.address, ty, request.header.counter, &data)
        {
            self.send(request, datagram).await;
        }
    }

    fn answered(&self, request: &Request) {
        self.stats.forwarded(request.received.elapsed());
    }
}

/// Runs until `stop` says so; then in-flight requests and TCP connections are dropped
/// with the runtime.
pub(crate) async fn run(
    shared: Arc<Shared>,
    listener: Option<TcpListener>,
    mut stop: watch::Receiver<bool>,
) {
    let mut buf = vec![0u8; RECEIVE_BUFFER];
    let mut tasks = JoinSet::new();
    tasks.spawn(shared.dictionary.tracker());
    let connections = tcp::Connections::new(shared.config.max_tcp_connections);
    loop {
        let (len, client) = tokio::select! {
            _ = stop.changed() => break,
            Some(_) = tasks.join_next(), if tasks.len() > 1 => continue,
            accepted = tcp::accept(listener.as_ref()) => {
                if let Ok((stream, peer)) = accepted
                    && let Some(connection) = connections.open(&shared, stream, peer)
                {
                    tasks.spawn(connection);
                }
                continue;
            }
            received = shared.socket.recv_from(&mut buf) => match received {
                Ok(r) => r,
                // ICMP port unreachable from an earlier reply, and the like: not fatal.
                Err(_) => continue,
            },
        };
        let received = StdInstant::now();
        shared.stats.received();
        if !shared.config.allows(client.ip()) {
            shared.stats.failed(FailureReason::Denied);
            continue;
        }
        let Some(datagram) = buf.get(..len) else {
            shared.stats.failed(FailureReason::Malformed);
            continue;
        };
        if let Admitted::Serve(request, ticket) =
            admit(&shared, datagram, client, ReplyTo::Udp, received).await
        {
            tasks.spawn(serve(Arc::clone(&shared), request, ticket));
        }
    }
}

fn parse(
    datagram: &[u8],
    client: SocketAddr,
    received: StdInstant,
    reply_to: ReplyTo,
) -> Option<Request> {
    let message = GatewayMessage::new_checked(datagram).ok()?;
    let repr = GatewayRepr::parse(&message).ok()?;
    let data = match repr.header.mailbox_type {
        MailboxType::Coe => normalize::coe_request(repr.data).into_owned(),
        _ => repr.data.to_vec(),
    };
    Some(Request {
        client,
        header: repr.header,
        data,
        received,
        reply_to,
    })
}

/// Works on one admitted request and sends its replies.
pub(crate) async fn serve(shared: Arc<Shared>, request: Request, _ticket: Ticket) {
    match route::target(&shared.master, request.header.address) {
        Ok(Target::Master) => to_master(&shared, &request).await,
        Ok(Target::Slave(station)) => to_slave(&shared, &request, station).await,
        Ok(Target::Broadcast) => broadcast(&shared, &request).await,
        Err(fault) => shared.fail(&request, fault).await,
    }
}

async fn to_master(shared: &Shared, request: &Request) {
    if request.header.mailbox_type != MailboxType::Coe {
        return shared.fail(request, Fault::Unsupported).await;
    }
    let replies = shared
        .dictionary
        .handle(request.client, &request.data)
        .await;
    shared.answered(request);
    for (ty, data) in replies {
        if let Some(datagram) =
            reply::made(request.header.address, ty, request.header.counter, &data)
        {
            shared.send(request, datagram).await;
        }
    }
}

fn forward_for<'a>(shared: &'a Shared, request: &Request, sessions: bool) -> Forward<'a> {
    Forward {
        sessions: sessions.then_some(&shared.sessions),
        client: request.client,
        deadline: Instant::now() + shared.config.request_timeout,
        session_timeout: shared.config.session_timeout,
    }
}

async fn to_slave(shared: &Shared, request: &Request, station: u16) {
    let ty = request.header.mailbox_type;
    let mailbox = match route::mailbox(&shared.master, station, ty) {
        Ok(mailbox) => mailbox,
        Err(fault) => return shared.fail(request, fault).await,
    };
    let f = forward_for(shared, request, true);
    match forward(&f, &mailbox, ty, &request.data).await {
        Ok(replies) => {
            shared.answered(request);
            for message in replies {
                if let Some(datagram) = reply::from_slave(request.header.address, &message) {
                    shared.send(request, datagram).await;
                }
            }
        }
        Err(fault) => shared.fail(request, fault).await,
    }
}

/// Sends the request to every slave that serves its protocol at once; each answer goes to
/// the client as its own datagram, as it comes, carrying the answering slave's station
/// address. Broadcasts take no sessions (a multi-message transfer with every slave at once
/// is not something a client can drive).
async fn broadcast(shared: &Arc<Shared>, request: &Request) {
    let ty = request.header.mailbox_type;
    let targets: Vec<_> = shared
        .master
        .slaves()
        .iter()
        .filter_map(|s| route::mailbox(&shared.master, s.station, ty).ok())
        .collect();
    if targets.is_empty() {
        return shared.fail(request, Fault::UnknownAddress).await;
    }
    let mut tasks = JoinSet::new();
    let data: Arc<[u8]> = Arc::from(request.data.as_slice());
    for mailbox in targets {
        let shared = Arc::clone(shared);
        let data = Arc::clone(&data);
        let client = request.client;
        tasks.spawn(async move {
            let f = Forward {
                sessions: None,
                client,
                deadline: Instant::now() + shared.config.request_timeout,
                session_timeout: shared.config.session_timeout,
            };
            let result = forward(&f, &mailbox, ty, &data).await;
            (mailbox.station(), result)
        });
    }
    let mut any = false;
    let mut last_fault = Fault::Timeout;
    while let Some(joined) = tasks.join_next().await {
        let Ok((station, result)) = joined else {
            continue;
        };
        match result {
            Ok(replies) => {
                if !any {
                    shared.answered(request);
                    any = true;
                }
                for message in replies {
                    if let Some(datagram) = reply::from_slave(station, &message) {
                        shared.send(request, datagram).await;
                    }
                }
            }
            Err(fault) => last_fault = fault,
        }
    }
    if !any {
        shared.fail(request, last_fault).await;
    }
}
