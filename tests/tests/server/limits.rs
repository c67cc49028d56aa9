//! Issue 35, points 2 and 3: the API servers bound their connections (`[limits]`) and their
//! request bodies, before any token is checked.
//!
//! Against `ecatd --simulate` with short limits, over real sockets: a connection that sends
//! half a request line (or nothing, or only the HTTP/2 preface) is closed after
//! `header_read_timeout`; a kept-alive connection after its answer is closed (HTTP/1.1 by
//! hyper's header-read timeout, HTTP/2 and gRPC after `idle_timeout`); connections over the
//! per-address cap are refused while the first ones still answer; 500 idle connections
//! cost a bounded amount of memory; a body declared or streamed past 16 MiB gets 413 before
//! the rest is read. Timings are checked as sanity bounds (closed, and not before the
//! deadline was due), not as goals.

use crate::server_support;

use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use server_support::{Ecatd, curl};

/// The short limits most tests run under.
const SHORT: &str = "[limits]\nheader_read_timeout = \"1s\"\nidle_timeout = \"2s\"\nmax_connections = 50\nmax_connections_per_peer = 10\n";
/// `header_read_timeout` and `idle_timeout` of [`SHORT`].
const HEADER_READ: Duration = Duration::from_secs(1);
const IDLE: Duration = Duration::from_secs(2);
/// How long a test waits for the server to close a connection: far above every deadline
/// configured here, so a failure means "never closed", not "a little late".
const PATIENCE: Duration = Duration::from_secs(15);
/// The timer's slack a deadline may be seen early by (the server starts the deadline at its
/// accept, after the client's connect returned; the client measures from its side).
const SLACK: Duration = Duration::from_millis(100);
/// The request body limit (`http::MAX_BODY`).
const MAX_BODY: usize = 16 << 20;

/// ecatd on the simulated segment with `config` as its configuration file.
fn ecatd(name: &str, config: &str) -> (Ecatd, PathBuf) {
    let path =
        std::env::temp_dir().join(format!("ecatd-limits-{name}-{}.toml", std::process::id()));
    std::fs::write(&path, config).expect("config written");
    let ecatd = Ecatd::start(&["--config", path.to_str().expect("UTF-8 path")]);
    (ecatd, path)
}

/// `host:port` of the HTTP server.
fn http_addr(ecatd: &Ecatd) -> String {
    ecatd
        .http
        .strip_prefix("http://")
        .expect("plain HTTP")
        .to_owned()
}

fn connect(addr: &str) -> TcpStream {
    let stream = TcpStream::connect(addr).expect("connects");
    stream.set_nodelay(true).expect("nodelay");
    stream
}

/// How a connection ended.
#[derive(Debug, PartialEq, Eq)]
enum End {
    /// The server closed it (EOF or reset).
    Closed,
    /// Still open after the patience.
    Open,
}

/// Reads (and drops) whatever comes until the server closes the connection or `patience`
/// passes; returns how it ended, when, and the bytes read.
fn until_closed(stream: &mut TcpStream, patience: Duration) -> (End, Instant, Vec<u8>) {
    let deadline = Instant::now() + patience;
    let mut seen = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return (End::Open, Instant::now(), seen);
        }
        stream.set_read_timeout(Some(left)).expect("read timeout");
        match stream.read(&mut buf) {
            Ok(0) => return (End::Closed, Instant::now(), seen),
            Ok(n) => seen.extend_from_slice(&buf[..n]),
            Err(err) if matches!(err.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                return (End::Open, Instant::now(), seen);
            }
            Err(err) if err.kind() == ErrorKind::Interrupted => {}
            // Reset, aborted, ...: closed by the server.
            Err(_) => return (End::Closed, Instant::now(), seen),
        }
    }
}

/// An HTTP/1.1 answer: status, head and body.
#[derive(Debug)]
struct Answer {
    status: u16,
    head: String,
    body: Vec<u8>,
}

/// Reads one HTTP/1.1 answer with a `content-length` within `patience`; `None` if the
/// connection closed (or timed out) before a whole one came.
fn read_answer(stream: &mut TcpStream, patience: Duration) -> Option<Answer> {
    let deadline = Instant::now() + patience;
    let mut data = Vec::new();
    let mut buf = [0u8; 8192];
    loop {
        if let Some(end) = data.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&data[..end]).into_owned();
            let status = head.split(' ').nth(1)?.parse().ok()?;
            let length: usize = head
                .lines()
                .find_map(|l| {
                    let (name, value) = l.split_once(':')?;
                    name.eq_ignore_ascii_case("content-length")
                        .then(|| value.trim().parse().ok())?
                })
                .unwrap_or(0);
            if data.len() >= end + 4 + length {
                let body = data[end + 4..end + 4 + length].to_vec();
                return Some(Answer { status, head, body });
            }
        }
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return None;
        }
        stream.set_read_timeout(Some(left)).ok()?;
        match stream.read(&mut buf) {
            Ok(0) => return None,
            Ok(n) => data.extend_from_slice(&buf[..n]),
            Err(err) if err.kind() == ErrorKind::Interrupted => {}
            Err(_) => return None,
        }
    }
}

/// A complete keep-alive GET of `path`.
fn get(stream: &mut TcpStream, path: &str) -> Option<Answer> {
    let request = format!("GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
    stream.write_all(request.as_bytes()).ok()?;
    read_answer(stream, PATIENCE)
}

/// Checks that a connection the server closed was closed by its deadline, not before it
/// was due: `elapsed` measured from a moment no later than the server's start of it.
fn closed_on_time(what: &str, end: End, elapsed: Duration, due: Duration) {
    assert_eq!(end, End::Closed, "{what}: still open after {PATIENCE:?}");
    assert!(
        elapsed + SLACK >= due,
        "{what}: closed after {elapsed:?}, before its {due:?} deadline"
    );
    println!("{what}: closed after {elapsed:?} (deadline {due:?})");
}

/// A minimal HTTP/2 client over a plain socket: the preface, a request, the frames back.
mod h2 {
    use super::*;

    pub const PREFACE: &[u8] = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n";
    const DATA: u8 = 0;
    const HEADERS: u8 = 1;
    const SETTINGS: u8 = 4;
    const PING: u8 = 6;
    const END_STREAM: u8 = 1;
    const END_HEADERS: u8 = 4;
    const ACK: u8 = 1;

    pub fn frame(kind: u8, flags: u8, stream: u32, payload: &[u8]) -> Vec<u8> {
        let len = payload.len() as u32;
        let mut out = vec![(len >> 16) as u8, (len >> 8) as u8, len as u8, kind, flags];
        out.extend_from_slice(&stream.to_be_bytes());
        out.extend_from_slice(payload);
        out
    }

    /// The preface and an empty SETTINGS frame.
    pub fn handshake() -> Vec<u8> {
        let mut out = PREFACE.to_vec();
        out.extend(frame(SETTINGS, 0, 0, &[]));
        out
    }

    /// An HPACK literal header field without indexing, its name by static-table `index`
    /// (a 4-bit prefix: 15 and above continue in a second byte), its value short and plain.
    fn literal(index: u8, value: &str) -> Vec<u8> {
        let mut out = if index < 15 {
            vec![index]
        } else {
            vec![15, index - 15]
        };
        out.push(value.len() as u8);
        out.extend_from_slice(value.as_bytes());
        out
    }

    /// `GET path` on stream 1, with nothing to send after the headers.
    pub fn get(path: &str, authority: &str) -> Vec<u8> {
        // :method GET (static 2), :scheme http (6), :path (4), :authority (1).
        let mut block = vec![0x82, 0x86];
        block.extend(literal(4, path));
        block.extend(literal(1, authority));
        frame(HEADERS, END_STREAM | END_HEADERS, 1, &block)
    }

    /// A unary gRPC call of `path` with an empty message, on stream 1.
    pub fn grpc_call(path: &str, authority: &str) -> Vec<u8> {
        // :method POST (static 3), :scheme http, :path, :authority, content-type (31), te.
        let mut block = vec![0x83, 0x86];
        block.extend(literal(4, path));
        block.extend(literal(1, authority));
        block.extend(literal(31, "application/grpc"));
        block.extend([0x00, 2, b't', b'e', 8]);
        block.extend_from_slice(b"trailers");
        let mut out = frame(HEADERS, END_HEADERS, 1, &block);
        // Not compressed, length 0: an empty message.
        out.extend(frame(DATA, END_STREAM, 1, &[0, 0, 0, 0, 0]));
        out
    }

    /// Reads frames (acknowledging SETTINGS and PINGs) until stream 1 ends; returns the
    /// first header block the server sent on it. `None` if the connection ended first.
    pub fn until_answered(stream: &mut TcpStream, patience: Duration) -> Option<Vec<u8>> {
        stream.set_read_timeout(Some(patience)).ok()?;
        let mut first_headers = None;
        loop {
            let mut head = [0u8; 9];
            stream.read_exact(&mut head).ok()?;
            let len =
                (usize::from(head[0]) << 16) | (usize::from(head[1]) << 8) | usize::from(head[2]);
            let (kind, flags) = (head[3], head[4]);
            let id = u32::from_be_bytes([head[5], head[6], head[7], head[8]]) & 0x7fff_ffff;
            let mut payload = vec![0u8; len];
            stream.read_exact(&mut payload).ok()?;
            match kind {
                SETTINGS if flags & ACK == 0 => {
                    stream.write_all(&frame(SETTINGS, ACK, 0, &[])).ok()?;
                }
                PING if flags & ACK == 0 => {
                    stream.write_all(&frame(PING, ACK, 0, &payload)).ok()?;
                }
                HEADERS if id == 1 && first_headers.is_none() => {
                    first_headers = Some(payload);
                }
                _ => {}
            }
            if id == 1 && matches!(kind, DATA | HEADERS) && flags & END_STREAM != 0 {
                return first_headers;
            }
        }
    }

    /// `:status 200` is HPACK static entry 8: the first byte of the answer's block.
    pub fn is_200(block: &[u8]) -> bool {
        block.first() == Some(&0x88)
    }
}

#[test]
fn a_half_sent_request_head_is_closed_after_the_header_timeout() {
    let (ecatd, config) = ecatd("header", SHORT);
    let addr = http_addr(&ecatd);
    // Half a request line, and nothing at all: both closed at the deadline.
    let start = Instant::now();
    let mut partial = connect(&addr);
    partial.write_all(b"GET /healthz HT").expect("sent");
    let mut silent = connect(&addr);
    let (end, at, seen) = until_closed(&mut partial, PATIENCE);
    assert!(
        seen.is_empty() || seen.starts_with(b"HTTP/1.1 408"),
        "{}",
        String::from_utf8_lossy(&seen)
    );
    closed_on_time("partial request line", end, at - start, HEADER_READ);
    let (end, at, _) = until_closed(&mut silent, PATIENCE);
    closed_on_time("connection sending nothing", end, at - start, HEADER_READ);
    // The server still answers.
    assert_eq!(
        get(&mut connect(&addr), "/healthz").map(|a| a.status),
        Some(200)
    );
    let _ = std::fs::remove_file(config);
}

#[test]
fn an_idle_kept_alive_connection_is_closed() {
    let (ecatd, config) = ecatd("idle", SHORT);
    let addr = http_addr(&ecatd);
    // HTTP/1.1: after its answer the connection waits for the next request head, under
    // hyper's header-read timeout (the earlier of the two deadlines here).
    let mut http1 = connect(&addr);
    let answer = get(&mut http1, "/healthz").expect("answered");
    assert_eq!(answer.status, 200, "{}", answer.head);
    let answered = Instant::now();
    let (end, at, _) = until_closed(&mut http1, PATIENCE);
    closed_on_time("HTTP/1.1 kept alive", end, at - answered, HEADER_READ);

    // HTTP/2 (prior knowledge): hyper has no idle timeout of its own; ecatd closes the
    // connection `idle_timeout` after its last answer.
    let mut http2 = connect(&addr);
    let mut hello = h2::handshake();
    hello.extend(h2::get("/healthz", &addr));
    http2.write_all(&hello).expect("sent");
    let block = h2::until_answered(&mut http2, PATIENCE).expect("answered over HTTP/2");
    assert!(h2::is_200(&block), "HTTP/2 answer {block:02x?}");
    let answered = Instant::now();
    let (end, at, _) = until_closed(&mut http2, PATIENCE);
    closed_on_time("HTTP/2 idle", end, at - answered, IDLE);
    let _ = std::fs::remove_file(config);
}

#[test]
fn connections_over_the_per_address_cap_are_refused_and_the_first_ones_still_answer() {
    const PER_PEER: usize = 10;
    let (ecatd, config) = ecatd(
        "cap",
        &format!(
            "[limits]\nheader_read_timeout = \"20s\"\nidle_timeout = \"30s\"\nmax_connections = 50\nmax_connections_per_peer = {PER_PEER}\n"
        ),
    );
    let addr = http_addr(&ecatd);
    // The cap's worth of connections, each shown to be admitted by an answer (the start-up
    // readiness check's connection may still be closing: one refused is opened again).
    let mut held = Vec::new();
    for _ in 0..3 * PER_PEER {
        if held.len() == PER_PEER {
            break;
        }
        let mut stream = connect(&addr);
        if get(&mut stream, "/healthz").is_some_and(|a| a.status == 200) {
            held.push(stream);
        }
    }
    assert_eq!(held.len(), PER_PEER, "the first connections were admitted");
    let start = Instant::now();
    for i in 0..5 {
        let mut extra = connect(&addr);
        let (end, at, seen) = until_closed(&mut extra, PATIENCE);
        assert_eq!(end, End::Closed, "extra connection {i} kept");
        let text = String::from_utf8_lossy(&seen);
        assert!(
            seen.is_empty() || text.starts_with("HTTP/1.1 503 "),
            "extra connection {i}: {text}"
        );
        if !seen.is_empty() {
            assert!(
                text.contains("application/problem+json")
                    && text.contains("max_connections_per_peer"),
                "{text}"
            );
        }
        assert!(
            at - start < Duration::from_secs(5),
            "refused at once, not by the header timeout"
        );
    }
    // The admitted ones still work, and the refusals were counted.
    let answer = get(&mut held[0], "/metrics").expect("metrics over a held connection");
    assert_eq!(answer.status, 200);
    let text = String::from_utf8_lossy(&answer.body);
    let refused: f64 = text
        .lines()
        .find(|l| {
            l.starts_with("ecat_api_connections_refused_total{")
                && l.contains("server=\"http\"")
                && l.contains("reason=\"max_connections_per_peer\"")
        })
        .and_then(|l| l.rsplit(' ').next()?.parse().ok())
        .expect("refusals in the metrics");
    assert!(refused >= 5.0, "{refused} refusals counted");
    assert_eq!(
        get(&mut held[PER_PEER - 1], "/healthz").map(|a| a.status),
        Some(200)
    );

    // gRPC: the same cap on its own port; the extra connection is closed at once.
    let grpc = ecatd.grpc.clone();
    let mut grpc_held: Vec<TcpStream> = (0..PER_PEER).map(|_| connect(&grpc)).collect();
    // Every one admitted (a refused one would be closed at once, long before its deadline).
    for stream in &mut grpc_held {
        stream.write_all(&h2::handshake()).expect("preface sent");
    }
    let start = Instant::now();
    let mut extra = connect(&grpc);
    let (end, at, _) = until_closed(&mut extra, PATIENCE);
    assert_eq!(end, End::Closed, "extra gRPC connection kept");
    assert!(
        at - start < Duration::from_secs(5),
        "the extra gRPC connection was refused at once, not by the header timeout"
    );
    let (end, _, _) = until_closed(&mut grpc_held[0], Duration::from_millis(200));
    assert_eq!(end, End::Open, "an admitted gRPC connection is kept");
    let _ = std::fs::remove_file(config);
}

/// The process's resident memory (`VmRSS`), in KiB.
fn rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("/proc status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmRSS")
}

/// Waits until the server reports `want` or more open connections on `server`.
fn wait_open(ecatd: &Ecatd, server: &str, want: usize) -> f64 {
    let deadline = Instant::now() + PATIENCE;
    let url = format!("{}/metrics", ecatd.http);
    loop {
        let (status, body) = curl(&["-s", &url]);
        assert_eq!(status, 200);
        let open: f64 = body
            .lines()
            .find(|l| {
                l.starts_with("ecat_api_connections{")
                    && l.contains(&format!("server=\"{server}\""))
            })
            .and_then(|l| l.rsplit(' ').next()?.parse().ok())
            .expect("open connections in the metrics");
        if open >= want as f64 {
            return open;
        }
        assert!(
            Instant::now() < deadline,
            "{open} of {want} {server} connections open"
        );
        // Poll interval of the check; the loop ends on the count or the deadline.
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn idle_connections_cost_bounded_memory() {
    const CONNECTIONS: usize = 500;
    // Deadlines long enough that none closes while it is measured.
    let (ecatd, config) = ecatd(
        "memory",
        "[limits]\nheader_read_timeout = \"60s\"\nidle_timeout = \"60s\"\nmax_connections = 2048\nmax_connections_per_peer = 1024\n",
    );
    let pid = ecatd.pid();
    let addr = http_addr(&ecatd);
    // Warm up what the first requests allocate, so that only the connections are measured.
    for _ in 0..3 {
        assert_eq!(
            get(&mut connect(&addr), "/metrics").map(|a| a.status),
            Some(200)
        );
    }
    let before = rss_kib(pid);
    let http: Vec<TcpStream> = (0..CONNECTIONS)
        .map(|_| {
            let mut stream = connect(&addr);
            stream
                .write_all(b"GET /healthz HTTP/1.1\r\nHost: 127.")
                .expect("sent");
            stream
        })
        .collect();
    wait_open(&ecatd, "http", CONNECTIONS);
    let with_http = rss_kib(pid);
    let grpc: Vec<TcpStream> = (0..CONNECTIONS)
        .map(|_| {
            let mut stream = connect(&ecatd.grpc);
            stream.write_all(h2::PREFACE).expect("sent");
            stream
        })
        .collect();
    wait_open(&ecatd, "grpc", CONNECTIONS);
    let with_grpc = rss_kib(pid);
    let per = |from: u64, to: u64| (to.saturating_sub(from)) as f64 / CONNECTIONS as f64;
    println!(
        "RSS {before} KiB; +{CONNECTIONS} idle HTTP connections {with_http} KiB ({:.1} KiB each); +{CONNECTIONS} idle gRPC connections {with_grpc} KiB ({:.1} KiB each)",
        per(before, with_http),
        per(with_http, with_grpc)
    );
    assert!(
        with_grpc.saturating_sub(before) < 64 << 10,
        "{} KiB for {} idle connections",
        with_grpc - before,
        2 * CONNECTIONS
    );
    drop((http, grpc));
    let _ = std::fs::remove_file(config);
}

/// An FoE write: a PUT whose raw body is the file (up to the 16 MiB limit).
fn foe_put_head(extra: &str) -> String {
    format!(
        "PUT /api/v1/slaves/0/foe/big.bin HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/octet-stream\r\nX-Ecat-Client: tests\r\n{extra}\r\n"
    )
}

/// Checks a 413 problem details answer.
fn assert_too_large(answer: &Answer) {
    assert_eq!(
        answer.status,
        413,
        "{}\n{}",
        answer.head,
        String::from_utf8_lossy(&answer.body)
    );
    assert!(
        answer
            .head
            .to_ascii_lowercase()
            .contains("content-type: application/problem+json"),
        "{}",
        answer.head
    );
    let body: serde_json::Value = serde_json::from_slice(&answer.body).expect("JSON body");
    assert_eq!(body["status"], 413);
    assert_eq!(body["reason"], "TOO_LARGE");
}

#[test]
fn a_declared_body_over_the_limit_is_refused_before_it_is_read() {
    let (ecatd, config) = ecatd("declared", SHORT);
    let mut stream = connect(&http_addr(&ecatd));
    stream
        .write_all(foe_put_head("Content-Length: 104857600\r\n").as_bytes())
        .expect("head sent");
    // A little of the body: the answer must not wait for the rest (100 MB never come).
    let sent = stream.write(&[0u8; 64 << 10]).unwrap_or(0);
    let start = Instant::now();
    let answer = read_answer(&mut stream, PATIENCE).expect("answered without the body");
    println!(
        "413 after the head and {sent} bytes of a declared 104857600, in {:?}",
        start.elapsed()
    );
    assert_too_large(&answer);
    let text = String::from_utf8_lossy(&answer.body);
    assert!(text.contains("104857600"), "{text}");
    let (end, _, _) = until_closed(&mut stream, PATIENCE);
    assert_eq!(end, End::Closed, "the unread body's connection is closed");
    let _ = std::fs::remove_file(config);
}

#[test]
fn a_chunked_body_over_the_limit_is_cut_with_413() {
    let (ecatd, config) = ecatd("chunked", SHORT);
    let mut stream = connect(&http_addr(&ecatd));
    stream
        .write_all(foe_put_head("Transfer-Encoding: chunked\r\n").as_bytes())
        .expect("head sent");
    // 1 MiB chunks up to 2 MiB past the limit; the server may stop reading (and close)
    // once the limit is passed, so a failed or stalled write ends the sending.
    stream
        .set_write_timeout(Some(Duration::from_secs(5)))
        .expect("write timeout");
    let chunk = {
        let mut chunk = format!("{:x}\r\n", 1 << 20).into_bytes();
        chunk.extend(std::iter::repeat_n(b'x', 1 << 20));
        chunk.extend_from_slice(b"\r\n");
        chunk
    };
    let mut sent = 0usize;
    while sent <= MAX_BODY + (2 << 20) {
        if stream.write_all(&chunk).is_err() {
            break;
        }
        sent += 1 << 20;
    }
    let answer = read_answer(&mut stream, PATIENCE).expect("answered");
    println!("413 after {} MiB sent of a chunked body", sent >> 20);
    assert_too_large(&answer);
    let _ = std::fs::remove_file(config);
}

#[test]
fn an_idle_grpc_connection_is_closed() {
    let (ecatd, config) = ecatd("grpc", SHORT);
    let grpc = ecatd.grpc.clone();
    // No HTTP/2 preface at all, and the preface without a call: both within the header
    // timeout (tonic and hyper have no deadline for either).
    let start = Instant::now();
    let mut silent = connect(&grpc);
    let mut preface_only = connect(&grpc);
    preface_only.write_all(&h2::handshake()).expect("sent");
    let (end, at, _) = until_closed(&mut silent, PATIENCE);
    closed_on_time("gRPC without a preface", end, at - start, HEADER_READ);
    let (end, at, _) = until_closed(&mut preface_only, PATIENCE);
    closed_on_time("gRPC preface without a call", end, at - start, HEADER_READ);
    // A call, then nothing: closed `idle_timeout` after its answer.
    let mut called = connect(&grpc);
    let mut hello = h2::handshake();
    hello.extend(h2::grpc_call("/grpc.health.v1.Health/Check", &grpc));
    called.write_all(&hello).expect("sent");
    let block = h2::until_answered(&mut called, PATIENCE).expect("the call was answered");
    assert!(h2::is_200(&block), "gRPC answer {block:02x?}");
    let answered = Instant::now();
    let (end, at, _) = until_closed(&mut called, PATIENCE);
    closed_on_time("gRPC idle after a call", end, at - answered, IDLE);
    let _ = std::fs::remove_file(config);
}

/// Opens a TLS connection to `addr` offering `alpn` with `openssl s_client`, sends nothing
/// after the handshake, and waits (up to `patience`) for the server to close it; returns
/// how long that took from the start of the connection.
fn silent_tls(addr: &str, alpn: &str, patience: Duration) -> Option<Duration> {
    let start = Instant::now();
    let mut child = std::process::Command::new("openssl")
        .args(["s_client", "-connect", addr, "-alpn", alpn, "-quiet"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("openssl runs");
    // Kept open and empty: the client says nothing after the handshake.
    let stdin = child.stdin.take();
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait());
    });
    let ended = rx.recv_timeout(patience).ok().map(|_| start.elapsed());
    if ended.is_none() {
        // SAFETY: `kill` on our own child, which the waiting thread has not reaped (it is
        // still running).
        unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) };
    }
    drop(stdin);
    ended
}

#[test]
fn the_limits_hold_over_tls_too() {
    let certified =
        rcgen::generate_simple_self_signed(vec!["localhost".to_owned(), "127.0.0.1".to_owned()])
            .expect("certificate");
    let dir = std::env::temp_dir().join(format!("ecatd-limits-tls-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
    std::fs::write(&cert, certified.cert.pem()).expect("cert");
    std::fs::write(&key, certified.signing_key.serialize_pem()).expect("key");
    let (ecatd, config) = ecatd(
        "tls",
        &format!(
            "{SHORT}\n[tls]\ncert = {:?}\nkey = {:?}\n",
            cert.to_str().expect("UTF-8"),
            key.to_str().expect("UTF-8")
        ),
    );
    let https = ecatd
        .http
        .strip_prefix("https://")
        .expect("HTTPS with [tls]")
        .to_owned();
    // The deadline starts once the handshake is done: after the connection's start.
    for (addr, alpn, what) in [
        (https.as_str(), "http/1.1", "HTTPS, HTTP/1.1"),
        (https.as_str(), "h2", "HTTPS, HTTP/2"),
        (ecatd.grpc.as_str(), "h2", "gRPC over TLS"),
    ] {
        let elapsed = silent_tls(addr, alpn, PATIENCE);
        let end = if elapsed.is_some() {
            End::Closed
        } else {
            End::Open
        };
        closed_on_time(
            &format!("{what}, silent after the handshake"),
            end,
            elapsed.unwrap_or(PATIENCE),
            HEADER_READ,
        );
    }
    drop(ecatd);
    let _ = std::fs::remove_file(config);
    let _ = std::fs::remove_dir_all(dir);
}
