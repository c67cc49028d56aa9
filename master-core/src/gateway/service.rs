//! The transport-neutral service: a received message is parsed and admitted ([`admit`]),
//! then worked on ([`serve`]) and answered wherever its transport wants the replies
//! ([`ReplyTo`]). The UDP loop (`udp`) and the TCP connections (`tcp`) both hand their
//! messages here; neither knows the other.
//!
//! A request is turned into its standard form first (`compat`, `normalize`); [`serve`]
//! then answers a UDP repeat from the store (`retry`), refuses a `read` client's write
//! (`access`), routes it, and writes the audit line of a write (`audit`).

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant as StdInstant;

use tokio::net::UdpSocket;
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::mailbox::RawReply;
use crate::master::Master;
use crate::master_od::MasterDictionary;
use crate::wire::gateway::{GatewayMessage, GatewayRepr};
use crate::wire::mailbox::{MailboxErrorCode, MailboxHeader, MailboxType};

use super::admission::{Admission, Ticket};
use super::allow::GatewayRole;
use super::answer::{Fault, answer, mailbox_error};
use super::ask::Ask;
use super::audit::{self, Outcome};
use super::compat::{self, Layout};
use super::config::GatewayConfig;
use super::forward::{Forward, forward};
use super::normalize;
use super::reply;
use super::retry::{Check, Retries};
use super::route::{self, Target};
use super::session::{Patience, Sessions};
use super::stats::{FailureReason, Stats};

/// What every request task shares.
pub(crate) struct Shared {
    pub master: Arc<Master>,
    pub config: GatewayConfig,
    pub stats: Arc<Stats>,
    pub sessions: Sessions,
    pub admission: Arc<Admission>,
    pub dictionary: MasterDictionary,
    pub retries: Retries,
    /// Log lines the bus thread handed to the worker (`log_lines`).
    pub log_backlog: audit::Backlog,
}

/// Where the replies to a request go.
#[derive(Debug, Clone)]
pub(crate) enum ReplyTo {
    /// A datagram from the bound socket to the client's address and port.
    Udp(Arc<UdpSocket>),
    /// The same from a socket the bus thread serves (`on_bus`), which is non-blocking and
    /// not the runtime's: a datagram it cannot take at once is dropped, as a lost one.
    UdpStd(Arc<std::net::UdpSocket>),
    /// The writer of the client's TCP connection, in order.
    Tcp(mpsc::Sender<Vec<u8>>),
}

/// One request: who sent it, its header, its data (in the standard form), where replies go
/// and in which layout, what its client may do.
pub(crate) struct Request {
    client: SocketAddr,
    header: MailboxHeader,
    data: Vec<u8>,
    /// What `data` ask, read once when the request was admitted.
    ask: Ask,
    received: StdInstant,
    reply_to: ReplyTo,
    layout: Layout,
    role: GatewayRole,
    /// The message as received, for UDP requests that may be repeated (counter 1-7).
    raw: Option<Box<[u8]>>,
    /// The datagrams sent for it, kept for its repeats (with `raw` only).
    sent: Mutex<Vec<Vec<u8>>>,
}

/// What became of a received message.
pub(crate) enum Admitted {
    /// To be served (boxed: a request is ten times the size of the other variants, and it
    /// moves into a task that is allocated anyway).
    Serve(Box<Request>, Ticket),
    /// Answered or dropped already (busy), counted.
    Done,
    /// Not a gateway message; counted.
    Malformed,
}

/// Counts a datagram just received into `buf` (`len` bytes, as the socket said) and
/// screens it: its bytes and when it came, unless its client is not allowed or its length
/// is off (counted as failed, never answered). Both UDP loops (`udp`, `on_bus`) call it.
pub(crate) fn screened<'a>(
    shared: &Shared,
    buf: &'a [u8],
    len: usize,
    client: SocketAddr,
) -> Option<(&'a [u8], StdInstant)> {
    let received = StdInstant::now();
    shared.stats.received();
    if !shared.config.allows(client.ip()) {
        shared
            .stats
            .failed(FailureReason::Denied, received.elapsed());
        return None;
    }
    let Some(datagram) = buf.get(..len) else {
        shared
            .stats
            .failed(FailureReason::Malformed, received.elapsed());
        return None;
    };
    Some((datagram, received))
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
    // The caller checked the allowlist; a client it let through has a role.
    let role = shared
        .config
        .role_of(client.ip())
        .unwrap_or(GatewayRole::Read);
    let Some(request) = parse(message, client, received, reply_to, role) else {
        shared
            .stats
            .failed(FailureReason::Malformed, received.elapsed());
        return Admitted::Malformed;
    };
    shared.stats.parsed(request.header.mailbox_type);
    match shared.admission.admit(client) {
        Some(ticket) => Admitted::Serve(Box::new(request), ticket),
        None => {
            shared.fail(&request, Fault::Busy).await;
            Admitted::Done
        }
    }
}

impl Shared {
    async fn send(&self, request: &Request, datagram: Vec<u8>) {
        if request.raw.is_none() {
            self.send_only(request, datagram).await;
            return;
        }
        // Kept for repeats: sent from here, then moved into the store (no copy).
        match &request.reply_to {
            ReplyTo::Udp(socket) => {
                let _ = socket.send_to(&datagram, request.client).await;
            }
            ReplyTo::UdpStd(socket) => {
                let _ = socket.send_to(&datagram, request.client);
            }
            ReplyTo::Tcp(_) => {}
        }
        request
            .sent
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(datagram);
    }

    async fn send_only(&self, request: &Request, datagram: Vec<u8>) {
        match &request.reply_to {
            // A client that went away is its own problem; UDP has no one to tell.
            ReplyTo::Udp(socket) => {
                let _ = socket.send_to(&datagram, request.client).await;
            }
            ReplyTo::UdpStd(socket) => {
                let _ = socket.send_to(&datagram, request.client);
            }
            // A closed connection drops its writer: nothing left to send to.
            ReplyTo::Tcp(writer) => {
                let _ = writer.send(datagram).await;
            }
        }
    }

    /// Answers a failed request as the error table of its layout says (unless strict) and
    /// counts it.
    async fn fail(&self, request: &Request, fault: Fault) -> Outcome {
        self.stats
            .failed(fault.reason(), request.received.elapsed());
        self.answer_fault(request, fault, request.header.address)
            .await;
        Outcome::Failed(fault)
    }

    /// Sends the gateway's own answer to `request` for `fault` (unless strict), carrying
    /// `address`: the one the client used, or on a broadcast the slave it is about. Counts
    /// nothing.
    async fn answer_fault(&self, request: &Request, fault: Fault, address: u16) {
        if self.config.strict {
            return;
        }
        let ty = request.header.mailbox_type;
        let answer = match request.layout {
            Layout::Compat(_) => compat::answer(&request.ask, fault),
            Layout::Standard
                if address == route::MASTER_ADDRESS
                    && ty != MailboxType::Coe
                    && fault == Fault::Unsupported =>
            {
                Some(mailbox_error(MailboxErrorCode::UnsupportedProtocol))
            }
            Layout::Standard => answer(&request.ask, fault),
        };
        if let Some((ty, data)) = answer
            && let Some(datagram) =
                reply::made(address, ty, request.header.counter, &data, request.layout)
        {
            self.send(request, datagram).await;
        }
    }

    fn answered(&self, request: &Request) {
        self.stats.forwarded(request.received.elapsed());
    }
}

fn parse(
    datagram: &[u8],
    client: SocketAddr,
    received: StdInstant,
    reply_to: ReplyTo,
    role: GatewayRole,
) -> Option<Request> {
    let message = GatewayMessage::new_checked(datagram).ok()?;
    let repr = GatewayRepr::parse(&message).ok()?;
    let (header, data, layout) = match compat::request(&repr, compat::type_byte(&message)) {
        None => (repr.header, repr.data.to_vec(), Layout::Standard),
        Some(Ok(t)) => (t.header, t.data, Layout::Compat(t.compat)),
        Some(Err(())) => return None,
    };
    let data = match header.mailbox_type {
        // Most requests are standard already: keep their bytes, copy only a rewritten one.
        MailboxType::Coe => match normalize::coe_request(&data) {
            std::borrow::Cow::Borrowed(_) => data,
            std::borrow::Cow::Owned(rewritten) => rewritten,
        },
        _ => data,
    };
    // Only UDP loses replies; the layout without a counter never repeats.
    let raw = (matches!(reply_to, ReplyTo::Udp(_) | ReplyTo::UdpStd(_)) && header.counter != 0)
        .then(|| datagram.get(..message.total_len()).map(Box::from))
        .flatten();
    let ask = Ask::read(header.mailbox_type, &data);
    Some(Request {
        client,
        header,
        data,
        ask,
        received,
        reply_to,
        layout,
        role,
        raw,
        sent: Mutex::new(Vec::new()),
    })
}

/// Works on one admitted request and sends its replies.
pub(crate) async fn serve(shared: Arc<Shared>, request: Box<Request>, _ticket: Ticket) {
    let repeat = match &request.raw {
        Some(raw) => shared.retries.check(
            request.client,
            raw,
            request.header.counter,
            request.received,
        ),
        None => Check::New(None),
    };
    let ticket = match repeat {
        Check::New(ticket) => ticket,
        Check::Repeat(datagrams) => {
            shared.stats.retry_answered();
            for datagram in datagrams {
                shared.send_only(&request, datagram).await;
            }
            return;
        }
        Check::InFlight => {
            shared.stats.retry_answered();
            return;
        }
    };
    let address = request.header.address;
    let write = request.ask.is_write();
    let refused = write && request.role < GatewayRole::Write;
    let outcome = if refused {
        shared.fail(&request, Fault::Denied).await
    } else {
        match route::target(&shared.master, address) {
            Ok(Target::Master) => to_master(&shared, &request).await,
            Ok(Target::Slave(station)) => to_slave(&shared, &request, station).await,
            Ok(Target::Broadcast) => broadcast(&shared, &request).await,
            Err(fault) => shared.fail(&request, fault).await,
        }
    };
    log_lines(&shared, &request, refused, &outcome);
    if let Some(ticket) = ticket {
        // "Busy" and "no answer in time" are no final answer: a repeat may run.
        let final_answer = !matches!(outcome, Outcome::Failed(Fault::Busy | Fault::Timeout));
        let sent =
            std::mem::take(&mut *request.sent.lock().unwrap_or_else(PoisonError::into_inner));
        shared.retries.finish(
            request.client,
            ticket,
            final_answer.then_some(sent),
            StdInstant::now(),
        );
    }
}

/// Writes a request's audit line (a write, or a write refused) and its failure line. On the
/// bus thread (`on_bus`) a line that will be written at all is handed to the gateway's
/// worker while the backlog of such lines has room ([`audit::Backlog`]), so that a log
/// that blocks (a stalled journal) does not hold up the thread that owns the link; the rest
/// (reads, whose failures log at `debug`) are filtered in place, at no cost.
fn log_lines(shared: &Shared, request: &Request, refused: bool, outcome: &Outcome) {
    let address = request.header.address;
    let write = request.ask.is_write();
    let lines = move |client: SocketAddr, ask: &Ask, outcome: &Outcome| {
        if refused {
            audit::refused(client, address, ask);
        } else if write {
            audit::write(client, address, ask, outcome);
        }
        audit::failure(client, address, ask, outcome);
    };
    let loud = write || audit::failure_is_loud(&request.ask, outcome);
    let handed = (loud && super::on_bus::serving())
        .then(|| shared.log_backlog.enter())
        .flatten();
    match handed {
        Some(place) => {
            let (client, ask, outcome) = (request.client, request.ask.clone(), outcome.clone());
            drop(tokio::spawn(async move {
                lines(client, &ask, &outcome);
                drop(place);
            }));
        }
        None => lines(request.client, &request.ask, outcome),
    }
}

/// The outcome of a request answered with `replies`.
fn answered_with(replies: &[RawReply]) -> Outcome {
    match replies.first() {
        Some(first) => Outcome::answered(first.mailbox_type(), first.data()),
        None => Outcome::Sent,
    }
}

async fn to_master(shared: &Shared, request: &Request) -> Outcome {
    if request.header.mailbox_type != MailboxType::Coe {
        return shared.fail(request, Fault::Unsupported).await;
    }
    let replies = shared
        .dictionary
        .handle(request.client, &request.data)
        .await;
    shared.answered(request);
    let outcome = match replies.first() {
        Some((ty, data)) => Outcome::answered(*ty, data),
        None => Outcome::Sent,
    };
    for (ty, data) in replies {
        if let Some(datagram) = reply::made(
            request.header.address,
            ty,
            request.header.counter,
            &data,
            request.layout,
        ) {
            shared.send(request, datagram).await;
        }
    }
    outcome
}

fn forward_for(shared: &Shared, client: SocketAddr, patience: Patience) -> Forward<'_> {
    Forward {
        sessions: &shared.sessions,
        patience,
        client,
        deadline: Instant::now() + shared.config.request_timeout,
        session_timeout: shared.config.session_timeout,
    }
}

async fn to_slave(shared: &Shared, request: &Request, station: u16) -> Outcome {
    let ty = request.header.mailbox_type;
    let mailbox = match route::mailbox(&shared.master, station, ty) {
        Ok(mailbox) => mailbox,
        Err(fault) => return shared.fail(request, fault).await,
    };
    let f = forward_for(shared, request.client, Patience::AnyHolder);
    match forward(&f, &mailbox, &request.ask, &request.data).await {
        Ok(replies) => {
            shared.answered(request);
            let outcome = answered_with(&replies);
            for message in replies {
                if let Some(datagram) =
                    reply::from_slave(request.header.address, &message, request.layout)
                {
                    shared.send(request, datagram).await;
                }
            }
            outcome
        }
        Err(fault) => shared.fail(request, fault).await,
    }
}

/// Sends the request to every slave that serves its protocol at once; each answer goes to
/// the client as its own datagram, as it comes, carrying the answering slave's station
/// address.
///
/// For each slave the broadcast is a message of its client like any other (it holds the
/// slave for the exchange, and a transfer it opens is the client's, to go on with at the
/// slave's own address), except that it does not wait for another client's transfer: such
/// a slave is skipped and answers "busy" (mailbox error 0x0009) with its station address,
/// so that no client, whatever its role, steps into another's transfer, and the other
/// slaves' answers do not wait for a transfer that may last long. A message that continues a
/// transfer is refused before any slave sees it (spec-notes §gateway.broadcast).
async fn broadcast(shared: &Arc<Shared>, request: &Request) -> Outcome {
    let ty = request.header.mailbox_type;
    if !request.ask.broadcastable() {
        return shared.fail(request, Fault::NotBroadcast).await;
    }
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
    let ask = Arc::new(request.ask.clone());
    for mailbox in targets {
        let shared = Arc::clone(shared);
        let data = Arc::clone(&data);
        let ask = Arc::clone(&ask);
        let client = request.client;
        tasks.spawn(async move {
            let f = forward_for(&shared, client, Patience::ExchangeOnly);
            let result = forward(&f, &mailbox, &ask, &data).await;
            (mailbox.station(), result)
        });
    }
    let mut any = false;
    let mut busy = false;
    let mut outcome = Outcome::Sent;
    let mut last_fault = Fault::Timeout;
    while let Some(joined) = tasks.join_next().await {
        let Ok((station, result)) = joined else {
            continue;
        };
        match result {
            Ok(replies) => {
                if !any {
                    shared.answered(request);
                    outcome = answered_with(&replies);
                    any = true;
                }
                for message in replies {
                    if let Some(datagram) = reply::from_slave(station, &message, request.layout) {
                        shared.send(request, datagram).await;
                    }
                }
            }
            // Held by another client's transfer (or still held, or its queue full, at the
            // deadline): the client learns which slave it did not reach, and may ask it
            // again at its own address.
            Err(Fault::Busy) => {
                busy = true;
                shared.answer_fault(request, Fault::Busy, station).await;
            }
            Err(fault) => last_fault = fault,
        }
    }
    if any {
        return outcome;
    }
    if busy {
        // No slave answered and the busy ones have their answers already: counted once, as
        // busy, which is no final answer (a repeat of the datagram runs again).
        shared
            .stats
            .failed(Fault::Busy.reason(), request.received.elapsed());
        return Outcome::Failed(Fault::Busy);
    }
    shared.fail(request, last_fault).await
}
