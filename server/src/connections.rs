//! Connection limits shared by the HTTP and gRPC servers (`[limits]`): how many connections
//! are open at once (in total and per client address), how long a connection may take to
//! send its first request, and how long it may stay idle.
//!
//! Each accepted connection is first admitted by a [`Limiter`] (a [`Permit`] it keeps while
//! open), then wrapped in a [`LimitedIo`] that ends it when its deadline passes with no
//! request in flight: `header_read_timeout` after the accept until the first request,
//! `idle_timeout` after each answer. Requests count as in flight from the moment the server
//! hands them to the application until their response body has been sent ([`Tracked`]), so
//! an event stream or a long FoE transfer is never cut as idle. A write that makes no
//! progress for `idle_timeout` (a client that does not read its answer) also ends the
//! connection.
//!
//! The deadlines live in the connection's I/O rather than in hyper because hyper has no
//! idle timeout for HTTP/2 at all, and neither hyper nor tonic bounds the wait for the
//! HTTP/2 preface; HTTP/1.1's own header-read timeout (hyper's, which needs a timer) is set
//! as well, see `http::serve`.

use std::collections::HashMap;
use std::io;
use std::net::{IpAddr, SocketAddr};
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::{Bytes, HttpBody};
use axum::http;
use futures_util::task::AtomicWaker;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::{Instant, Sleep};

use crate::config::limits::LimitSettings;

/// Why a connection was refused at its accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// `max_connections` are open.
    Total,
    /// `max_connections_per_peer` are open from the client's address.
    Peer,
}

impl Refusal {
    /// The `reason` label and the text a refused client is told.
    pub fn text(self) -> (&'static str, &'static str) {
        match self {
            Refusal::Total => ("max_connections", "too many connections"),
            Refusal::Peer => (
                "max_connections_per_peer",
                "too many connections from this address",
            ),
        }
    }
}

/// Why a connection was ended by the server.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timeout {
    /// No whole request head within `header_read_timeout`.
    HeaderRead,
    /// No request in flight for `idle_timeout`.
    Idle,
    /// A write that made no progress for `idle_timeout`.
    WriteStall,
}

/// One server's connection counters, read by `/metrics`.
#[derive(Debug, Default)]
pub struct ConnectionStats {
    open: AtomicU64,
    refused_total: AtomicU64,
    refused_peer: AtomicU64,
    header_read: AtomicU64,
    idle: AtomicU64,
    write_stall: AtomicU64,
}

impl ConnectionStats {
    fn refused(&self, refusal: Refusal) {
        match refusal {
            Refusal::Total => &self.refused_total,
            Refusal::Peer => &self.refused_peer,
        }
        .fetch_add(1, Ordering::Relaxed);
    }

    /// Counts a connection the server ended for `timeout`.
    pub fn timed_out(&self, timeout: Timeout) {
        match timeout {
            Timeout::HeaderRead => &self.header_read,
            Timeout::Idle => &self.idle,
            Timeout::WriteStall => &self.write_stall,
        }
        .fetch_add(1, Ordering::Relaxed);
    }

    /// Connections open now.
    pub fn open(&self) -> u64 {
        self.open.load(Ordering::Relaxed)
    }

    /// Every counter now.
    pub fn counts(&self) -> ConnectionCounts {
        let load = |n: &AtomicU64| n.load(Ordering::Relaxed);
        ConnectionCounts {
            open: load(&self.open),
            refused_total: load(&self.refused_total),
            refused_peer: load(&self.refused_peer),
            header_read: load(&self.header_read),
            idle: load(&self.idle),
            write_stall: load(&self.write_stall),
        }
    }
}

/// One server's counters as [`ConnectionStats::counts`] reads them.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ConnectionCounts {
    /// Open now.
    pub open: u64,
    /// Refused by `max_connections`.
    pub refused_total: u64,
    /// Refused by `max_connections_per_peer`.
    pub refused_peer: u64,
    /// Closed without a whole request head within `header_read_timeout`.
    pub header_read: u64,
    /// Closed after `idle_timeout` without a request.
    pub idle: u64,
    /// Closed after a write made no progress for `idle_timeout`.
    pub write_stall: u64,
}

/// The counters of both servers, kept with the metrics (`metrics::Store`).
#[derive(Debug, Default)]
pub struct ServerStats {
    /// The HTTP server (REST, dashboard, metrics, health).
    pub http: Arc<ConnectionStats>,
    /// The gRPC server.
    pub grpc: Arc<ConnectionStats>,
}

/// Counts open connections, in total and per client address, against `[limits]`, and
/// gives each admitted one its deadlines.
#[derive(Debug)]
pub struct Limiter {
    max_total: usize,
    max_peer: usize,
    timeouts: Timeouts,
    stats: Arc<ConnectionStats>,
    /// Open connections per address; an address leaves the map with its last connection,
    /// so the map holds at most `max_total` entries.
    open: Mutex<(usize, HashMap<IpAddr, usize>)>,
}

impl Limiter {
    /// A limiter for one server, counting into `stats`.
    pub fn new(limits: &LimitSettings, stats: Arc<ConnectionStats>) -> Arc<Limiter> {
        Arc::new(Limiter {
            max_total: limits.max_connections,
            max_peer: limits.max_connections_per_peer,
            timeouts: Timeouts::from(limits),
            stats,
            open: Mutex::new((0, HashMap::new())),
        })
    }

    /// Admits the connection `io` from `peer` with its deadlines, or gives it back with the
    /// limit that refuses it (counted; the caller answers or just closes it).
    pub fn accept<IO>(
        self: &Arc<Limiter>,
        io: IO,
        peer: SocketAddr,
    ) -> Result<LimitedIo<IO>, (IO, Refusal)> {
        let permit = match self.admit(peer.ip()) {
            Ok(permit) => permit,
            Err(refusal) => {
                tracing::debug!(%peer, ?refusal, "connection refused by [limits]");
                return Err((io, refusal));
            }
        };
        Ok(LimitedIo::new(
            io,
            peer,
            permit,
            Activity::new(),
            self.timeouts,
            Arc::clone(&self.stats),
        ))
    }

    /// Admits a connection from `peer`, or says which limit refuses it (and counts it).
    fn admit(self: &Arc<Limiter>, peer: IpAddr) -> Result<Permit, Refusal> {
        // An IPv4 client on a dual-stack socket is the same client as on an IPv4 one.
        let peer = peer.to_canonical();
        let mut open = self.open.lock().unwrap_or_else(PoisonError::into_inner);
        let (total, peers) = &mut *open;
        let refusal = if *total >= self.max_total {
            Some(Refusal::Total)
        } else if peers.get(&peer).copied().unwrap_or(0) >= self.max_peer {
            Some(Refusal::Peer)
        } else {
            None
        };
        if let Some(refusal) = refusal {
            drop(open);
            self.stats.refused(refusal);
            return Err(refusal);
        }
        *total += 1;
        *peers.entry(peer).or_insert(0) += 1;
        self.stats.open.store(*total as u64, Ordering::Relaxed);
        Ok(Permit {
            limiter: Arc::clone(self),
            peer,
        })
    }
}

/// One admitted connection's place; given back when dropped (with the connection's I/O).
#[derive(Debug)]
pub struct Permit {
    limiter: Arc<Limiter>,
    peer: IpAddr,
}

impl Drop for Permit {
    fn drop(&mut self) {
        let mut open = self
            .limiter
            .open
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let (total, peers) = &mut *open;
        *total = total.saturating_sub(1);
        if let Some(n) = peers.get_mut(&self.peer) {
            *n -= 1;
            if *n == 0 {
                peers.remove(&self.peer);
            }
        }
        self.limiter
            .stats
            .open
            .store(*total as u64, Ordering::Relaxed);
    }
}

/// What a connection is doing: requests in flight, and since when it is idle.
#[derive(Debug)]
pub struct Activity {
    state: Mutex<ActivityState>,
    /// The connection's reader, woken when its last request ends so that it arms the idle
    /// deadline (nothing else would poll it while the client is silent).
    reader: AtomicWaker,
}

#[derive(Debug)]
struct ActivityState {
    in_flight: usize,
    requests: u64,
    idle_since: Instant,
}

impl Activity {
    /// A connection accepted now, with no request yet.
    pub fn new() -> Arc<Activity> {
        Arc::new(Activity {
            state: Mutex::new(ActivityState {
                in_flight: 0,
                requests: 0,
                idle_since: Instant::now(),
            }),
            reader: AtomicWaker::new(),
        })
    }

    /// A request starts; it is in flight until the guard is dropped (with its response body).
    pub fn begin(self: &Arc<Activity>) -> InFlight {
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        state.in_flight += 1;
        state.requests += 1;
        InFlight(Arc::clone(self))
    }

    /// When the connection is due to be closed, and why; `None` while a request is in
    /// flight.
    fn deadline(&self, timeouts: Timeouts) -> Option<(Instant, Timeout)> {
        let state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        match (state.in_flight, state.requests) {
            (0, 0) => Some((state.idle_since + timeouts.header_read, Timeout::HeaderRead)),
            (0, _) => Some((state.idle_since + timeouts.idle, Timeout::Idle)),
            _ => None,
        }
    }
}

/// A request in flight on its connection ([`Activity::begin`]).
#[derive(Debug)]
pub struct InFlight(Arc<Activity>);

impl Drop for InFlight {
    fn drop(&mut self) {
        let mut state = self.0.state.lock().unwrap_or_else(PoisonError::into_inner);
        state.in_flight -= 1;
        if state.in_flight == 0 {
            state.idle_since = Instant::now();
        }
        drop(state);
        self.0.reader.wake();
    }
}

/// The two deadlines of a connection, from `[limits]`.
#[derive(Debug, Clone, Copy)]
pub struct Timeouts {
    /// Accept to first request.
    pub header_read: Duration,
    /// Last answer to the next request, and a stalled write.
    pub idle: Duration,
}

impl From<&LimitSettings> for Timeouts {
    fn from(limits: &LimitSettings) -> Timeouts {
        Timeouts {
            header_read: limits.header_read_timeout,
            idle: limits.idle_timeout,
        }
    }
}

/// A connection's I/O with its [`Permit`] and deadlines: once the deadline passes with no
/// request in flight, reads fail with `TimedOut` and the server drops the connection.
#[derive(Debug)]
pub struct LimitedIo<IO> {
    inner: IO,
    peer: SocketAddr,
    activity: Arc<Activity>,
    timeouts: Timeouts,
    stats: Arc<ConnectionStats>,
    deadline: Pin<Box<Sleep>>,
    /// Armed while a write is pending (`stalled`); the connection ends if it stays so for
    /// `idle`. One timer for the connection's life, reset per stall.
    stall: Pin<Box<Sleep>>,
    stalled: bool,
    expired: bool,
    _permit: Permit,
}

impl<IO> LimitedIo<IO> {
    /// `inner` from `peer`, admitted with `permit`, its requests tracked by `activity`.
    fn new(
        inner: IO,
        peer: SocketAddr,
        permit: Permit,
        activity: Arc<Activity>,
        timeouts: Timeouts,
        stats: Arc<ConnectionStats>,
    ) -> LimitedIo<IO> {
        let first = Instant::now() + timeouts.header_read;
        LimitedIo {
            inner,
            peer,
            activity,
            timeouts,
            stats,
            deadline: Box::pin(tokio::time::sleep_until(first)),
            stall: Box::pin(tokio::time::sleep_until(first)),
            stalled: false,
            expired: false,
            _permit: permit,
        }
    }

    /// What the server's request layer needs to track this connection's requests.
    pub fn info(&self) -> ConnInfo {
        ConnInfo {
            peer: self.peer,
            activity: Arc::clone(&self.activity),
        }
    }

    fn expire(&mut self, why: Timeout) -> io::Error {
        if !self.expired {
            self.expired = true;
            self.stats.timed_out(why);
            tracing::debug!(peer = %self.peer, ?why, "connection closed by [limits]");
        }
        io::Error::new(io::ErrorKind::TimedOut, "connection closed by [limits]")
    }

    fn poll_stall(&mut self, cx: &mut Context<'_>) -> Poll<io::Error> {
        if !self.stalled {
            self.stalled = true;
            let due = Instant::now() + self.timeouts.idle;
            self.stall.as_mut().reset(due);
        }
        match self.stall.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(self.expire(Timeout::WriteStall)),
            Poll::Pending => Poll::Pending,
        }
    }

    /// A write that made progress ends a stall; one that could not starts (or continues)
    /// the stall's clock.
    fn after_write(
        &mut self,
        cx: &mut Context<'_>,
        written: Poll<io::Result<usize>>,
    ) -> Poll<io::Result<usize>> {
        match written {
            Poll::Ready(written) => {
                self.stalled = false;
                Poll::Ready(written)
            }
            Poll::Pending => self.poll_stall(cx).map(Err),
        }
    }
}

impl<IO: AsyncRead + Unpin> AsyncRead for LimitedIo<IO> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        if this.expired {
            return Poll::Ready(Err(this.expire(Timeout::Idle)));
        }
        if let Poll::Ready(read) = Pin::new(&mut this.inner).poll_read(cx, buf) {
            return Poll::Ready(read);
        }
        // Registered before the check, so that a request ending after it wakes this reader.
        this.activity.reader.register(cx.waker());
        let Some((due, why)) = this.activity.deadline(this.timeouts) else {
            return Poll::Pending;
        };
        if this.deadline.deadline() != due {
            this.deadline.as_mut().reset(due);
        }
        match this.deadline.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(this.expire(why))),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl<IO: AsyncWrite + Unpin> AsyncWrite for LimitedIo<IO> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let written = Pin::new(&mut this.inner).poll_write(cx, buf);
        this.after_write(cx, written)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let written = Pin::new(&mut this.inner).poll_write_vectored(cx, bufs);
        this.after_write(cx, written)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        match Pin::new(&mut this.inner).poll_flush(cx) {
            Poll::Ready(flushed) => {
                this.stalled = false;
                Poll::Ready(flushed)
            }
            Poll::Pending => this.poll_stall(cx).map(Err),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_shutdown(cx)
    }
}

/// A connection's address and activity, for the request layer: HTTP puts it in each
/// request itself, tonic through its `Connected` trait (as the request's connect info).
#[derive(Debug, Clone)]
pub struct ConnInfo {
    /// The client's address.
    pub peer: SocketAddr,
    /// The connection's requests.
    pub activity: Arc<Activity>,
}

impl<IO> tonic::transport::server::Connected for LimitedIo<IO> {
    type ConnectInfo = ConnInfo;

    fn connect_info(&self) -> ConnInfo {
        self.info()
    }
}

/// A response body that keeps its request in flight until it is sent or dropped.
#[derive(Debug)]
pub struct Tracked<B> {
    inner: B,
    _in_flight: Option<InFlight>,
}

impl<B> Tracked<B> {
    /// `inner`, with `in_flight` held until it ends.
    pub fn new(inner: B, in_flight: Option<InFlight>) -> Tracked<B> {
        Tracked {
            inner,
            _in_flight: in_flight,
        }
    }
}

impl<B: HttpBody + Unpin> HttpBody for Tracked<B> {
    type Data = B::Data;
    type Error = B::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<B::Data>, B::Error>>> {
        Pin::new(&mut self.get_mut().inner).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

/// The gRPC server's request layer: marks each call in flight on its connection (from the
/// [`ConnInfo`] tonic puts in the request) until its response stream ends.
#[derive(Debug, Clone, Copy, Default)]
pub struct TrackLayer;

impl<S> tower_layer::Layer<S> for TrackLayer {
    type Service = TrackService<S>;

    fn layer(&self, inner: S) -> TrackService<S> {
        TrackService { inner }
    }
}

/// A service whose calls are tracked ([`TrackLayer`]).
#[derive(Debug, Clone)]
pub struct TrackService<S> {
    inner: S,
}

impl<S, B, R> tower_service::Service<http::Request<B>> for TrackService<S>
where
    S: tower_service::Service<http::Request<B>, Response = http::Response<R>>,
    S::Future: Send + 'static,
    R: HttpBody<Data = Bytes> + Unpin,
{
    type Response = http::Response<Tracked<R>>;
    type Error = S::Error;
    type Future =
        Pin<Box<dyn std::future::Future<Output = Result<Self::Response, S::Error>> + Send>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), S::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: http::Request<B>) -> Self::Future {
        let in_flight = request
            .extensions()
            .get::<ConnInfo>()
            .map(|info| info.activity.begin());
        let call = self.inner.call(request);
        Box::pin(async move {
            let response = call.await?;
            Ok(response.map(|body| Tracked::new(body, in_flight)))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(total: usize, peer: usize) -> LimitSettings {
        LimitSettings {
            max_connections: total,
            max_connections_per_peer: peer,
            ..LimitSettings::default()
        }
    }

    #[test]
    fn the_limiter_counts_per_peer_and_in_total_and_gives_places_back() {
        let stats = Arc::new(ConnectionStats::default());
        let limiter = Limiter::new(&limits(3, 2), Arc::clone(&stats));
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let a1 = limiter.admit(a).unwrap();
        let a2 = limiter.admit(a).unwrap();
        assert_eq!(limiter.admit(a).unwrap_err(), Refusal::Peer);
        // The same client over IPv4-mapped IPv6.
        let mapped: IpAddr = "::ffff:10.0.0.1".parse().unwrap();
        assert_eq!(limiter.admit(mapped).unwrap_err(), Refusal::Peer);
        let b1 = limiter.admit(b).unwrap();
        assert_eq!(stats.open(), 3);
        assert_eq!(limiter.admit(b).unwrap_err(), Refusal::Total);
        drop(a1);
        assert_eq!(stats.open(), 2);
        let b2 = limiter.admit(b).unwrap();
        drop((a2, b1, b2));
        assert_eq!(stats.open(), 0);
        assert!(
            limiter.open.lock().unwrap().1.is_empty(),
            "no address stays behind"
        );
        assert_eq!(stats.refused_peer.load(Ordering::Relaxed), 2);
        assert_eq!(stats.refused_total.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn deadlines_follow_the_requests_in_flight() {
        let timeouts = Timeouts {
            header_read: Duration::from_secs(1),
            idle: Duration::from_secs(5),
        };
        let accepted = Instant::now();
        let activity = Activity::new();
        let (due, why) = activity.deadline(timeouts).unwrap();
        assert_eq!(why, Timeout::HeaderRead);
        assert!(
            due >= accepted + timeouts.header_read && due <= Instant::now() + timeouts.header_read
        );
        let first = activity.begin();
        let second = activity.begin();
        assert_eq!(activity.deadline(timeouts), None);
        drop(first);
        assert_eq!(activity.deadline(timeouts), None, "one still in flight");
        let before = Instant::now();
        drop(second);
        let (due, why) = activity.deadline(timeouts).unwrap();
        assert_eq!(why, Timeout::Idle);
        assert!(
            due >= before + timeouts.idle,
            "counted from the last answer"
        );
    }

    #[tokio::test]
    async fn a_silent_connection_is_ended_at_its_deadline() {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let stats = Arc::new(ConnectionStats::default());
        let limiter = Limiter::new(&limits(4, 4), Arc::clone(&stats));
        let (client, server) = tokio::io::duplex(64);
        let peer: SocketAddr = "127.0.0.1:9".parse().unwrap();
        let timeouts = Timeouts {
            header_read: Duration::from_millis(100),
            idle: Duration::from_secs(2),
        };
        let activity = Activity::new();
        let mut io = LimitedIo::new(
            server,
            peer,
            limiter.admit(peer.ip()).unwrap(),
            Arc::clone(&activity),
            timeouts,
            Arc::clone(&stats),
        );
        let start = Instant::now();
        let mut client = client;
        client.write_all(b"GET / HT").await.unwrap();
        let mut buf = [0; 16];
        assert_eq!(io.read(&mut buf).await.unwrap(), 8, "bytes pass");
        let err = io.read(&mut buf).await.unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::TimedOut);
        let elapsed = start.elapsed();
        assert!(
            elapsed >= Duration::from_millis(90) && elapsed < Duration::from_secs(5),
            "{elapsed:?}"
        );
        assert_eq!(stats.header_read.load(Ordering::Relaxed), 1);
        drop(io);
        assert_eq!(stats.open(), 0, "the permit went with the connection");
    }
}
