//! A TCP endpoint behind the simulated EoE slave, built on smoltcp: an HTTP/1.0 server on
//! port 80 that answers `GET /<n>` with `n` bytes of [`payload_byte`], so a test can fetch
//! a known payload of any size through a master's EoE interface and check it. It answers
//! ARP itself (smoltcp); ICMP echo stays with the [`endpoint`](super::endpoint).
//!
//! Frames pass through two small in-memory queues (smoltcp's [`Device`]); the service feeds
//! the one and drains the other into the mailbox as it has room, so a slow master slows the
//! TCP sender down (its window) instead of losing frames.

use std::collections::VecDeque;
use std::net::Ipv4Addr;

use smoltcp::iface::{Config, Interface, SocketHandle, SocketSet};
use smoltcp::phy::{Device, DeviceCapabilities, Medium, RxToken, TxToken};
use smoltcp::socket::tcp;
use smoltcp::time::Instant;
use smoltcp::wire::{
    EthernetAddress, EthernetFrame, EthernetProtocol, HardwareAddress, IpCidr, IpProtocol,
    Ipv4Packet,
};

/// The port of the HTTP server.
pub const HTTP_PORT: u16 = 80;

/// The largest payload served (64 MiB).
pub const MAX_PAYLOAD: u64 = 64 << 20;

/// Frames smoltcp may have waiting for the mailbox before it holds back.
const TX_FRAMES: usize = 8;

/// Whether a frame is for the TCP host: ARP, or IPv4 carrying TCP.
pub fn wants(frame: &[u8]) -> bool {
    let Ok(ethernet) = EthernetFrame::new_checked(frame) else {
        return false;
    };
    match ethernet.ethertype() {
        EthernetProtocol::Arp => true,
        EthernetProtocol::Ipv4 => Ipv4Packet::new_checked(ethernet.payload())
            .is_ok_and(|ip| ip.next_header() == IpProtocol::Tcp),
        _ => false,
    }
}

/// Byte `offset` of every payload: counts through 0..=250 (a prime cycle, so a shifted or
/// repeated block does not match by chance).
pub fn payload_byte(offset: u64) -> u8 {
    (offset % 251) as u8
}

/// The frame queues smoltcp reads from and writes to.
#[derive(Debug, Default)]
struct Queues {
    rx: VecDeque<Vec<u8>>,
    tx: VecDeque<Vec<u8>>,
}

struct Rx(Vec<u8>);
struct Tx<'a>(&'a mut VecDeque<Vec<u8>>);

impl RxToken for Rx {
    fn consume<R, F: FnOnce(&[u8]) -> R>(self, f: F) -> R {
        f(&self.0)
    }
}

impl TxToken for Tx<'_> {
    fn consume<R, F: FnOnce(&mut [u8]) -> R>(self, len: usize, f: F) -> R {
        let mut frame = vec![0; len];
        let result = f(&mut frame);
        self.0.push_back(frame);
        result
    }
}

impl Device for Queues {
    type RxToken<'a> = Rx;
    type TxToken<'a> = Tx<'a>;

    fn receive(&mut self, _now: Instant) -> Option<(Rx, Tx<'_>)> {
        if self.tx.len() >= TX_FRAMES {
            return None;
        }
        let frame = self.rx.pop_front()?;
        Some((Rx(frame), Tx(&mut self.tx)))
    }

    fn transmit(&mut self, _now: Instant) -> Option<Tx<'_>> {
        (self.tx.len() < TX_FRAMES).then_some(Tx(&mut self.tx))
    }

    fn capabilities(&self) -> DeviceCapabilities {
        let mut caps = DeviceCapabilities::default();
        caps.medium = Medium::Ethernet;
        // A 1500-byte IP MTU, as the master's interface has.
        caps.max_transmission_unit = 1514;
        caps
    }
}

/// Where the HTTP exchange of the current connection is.
#[derive(Debug)]
enum Exchange {
    /// Reading the request (what came so far).
    Request(Vec<u8>),
    /// Sending: the header left, then the payload from `sent` to `len`.
    Sending {
        header: Vec<u8>,
        sent: u64,
        len: u64,
    },
    /// All sent; closing.
    Done,
}

/// The TCP host of one slave, for one MAC and IPv4 address.
pub struct TcpHost {
    mac: [u8; 6],
    ip: Ipv4Addr,
    prefix: u8,
    iface: Interface,
    device: Queues,
    sockets: SocketSet<'static>,
    socket: SocketHandle,
    exchange: Exchange,
    start: std::time::Instant,
}

impl std::fmt::Debug for TcpHost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TcpHost")
            .field("mac", &self.mac)
            .field("ip", &self.ip)
            .field("exchange", &self.exchange)
            .finish()
    }
}

impl TcpHost {
    /// A host at `mac` and `ip/prefix`, listening on [`HTTP_PORT`].
    pub fn new(mac: [u8; 6], ip: Ipv4Addr, prefix: u8) -> TcpHost {
        let start = std::time::Instant::now();
        let mut device = Queues::default();
        let config = Config::new(HardwareAddress::Ethernet(EthernetAddress(mac)));
        let mut iface = Interface::new(config, &mut device, Instant::from_micros(0));
        iface.update_ip_addrs(|addrs| {
            // One address: the vector's capacity is at least one.
            let _ = addrs.push(IpCidr::new(ip.into(), prefix));
        });
        let mut sockets = SocketSet::new(Vec::new());
        let socket = tcp::Socket::new(
            tcp::SocketBuffer::new(vec![0; 4096]),
            tcp::SocketBuffer::new(vec![0; 64 * 1024]),
        );
        let socket = sockets.add(socket);
        let mut host = TcpHost {
            mac,
            ip,
            prefix,
            iface,
            device,
            sockets,
            socket,
            exchange: Exchange::Request(Vec::new()),
            start,
        };
        host.listen();
        host
    }

    /// Whether this host has these settings.
    pub fn is_for(&self, mac: [u8; 6], ip: Ipv4Addr, prefix: u8) -> bool {
        (self.mac, self.ip, self.prefix) == (mac, ip, prefix)
    }

    fn listen(&mut self) {
        let socket = self.sockets.get_mut::<tcp::Socket>(self.socket);
        if !socket.is_open() {
            // Listening on a closed socket with a non-zero port cannot fail.
            let _ = socket.listen(HTTP_PORT);
            self.exchange = Exchange::Request(Vec::new());
        }
    }

    fn now(&self) -> Instant {
        let micros = i64::try_from(self.start.elapsed().as_micros()).unwrap_or(i64::MAX);
        Instant::from_micros(micros)
    }

    /// Takes a frame from the master.
    pub fn receive(&mut self, frame: Vec<u8>) {
        // Bounded: a master flooding the slave loses frames here, as on a real link.
        if self.device.rx.len() < 64 {
            self.device.rx.push_back(frame);
        }
    }

    /// Runs the stack and the server; frames to send to the master are then in
    /// [`Self::take_frame`].
    pub fn poll(&mut self) {
        for _ in 0..16 {
            let now = self.now();
            self.iface.poll(now, &mut self.device, &mut self.sockets);
            if !self.serve() {
                break;
            }
        }
    }

    /// The next frame for the master.
    pub fn take_frame(&mut self) -> Option<Vec<u8>> {
        self.device.tx.pop_front()
    }

    /// One step of the HTTP server; true if it did something (poll again).
    fn serve(&mut self) -> bool {
        let socket = self.sockets.get_mut::<tcp::Socket>(self.socket);
        if !socket.is_open() {
            self.listen();
            return false;
        }
        match &mut self.exchange {
            Exchange::Request(request) => {
                if !socket.can_recv() {
                    return false;
                }
                let _ = socket.recv(|data| {
                    request.extend_from_slice(data);
                    (data.len(), ())
                });
                if let Some(end) = find(request, b"\r\n\r\n") {
                    let header = respond(&request[..end]);
                    self.exchange = header;
                    return true;
                }
                if request.len() > 4096 {
                    socket.abort();
                }
                false
            }
            Exchange::Sending { header, sent, len } => {
                let mut progressed = false;
                if !header.is_empty() {
                    let n = socket.send_slice(header).unwrap_or(0);
                    header.drain(..n);
                    progressed |= n > 0;
                }
                while header.is_empty() && *sent < *len && socket.can_send() {
                    let offset = *sent;
                    let left = *len - offset;
                    let n = socket
                        .send(|buf| {
                            let n = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
                            for (i, b) in buf[..n].iter_mut().enumerate() {
                                *b = payload_byte(offset + i as u64);
                            }
                            (n, n)
                        })
                        .unwrap_or(0);
                    if n == 0 {
                        break;
                    }
                    *sent += n as u64;
                    progressed = true;
                }
                if header.is_empty() && *sent >= *len {
                    socket.close();
                    self.exchange = Exchange::Done;
                }
                progressed
            }
            Exchange::Done => {
                // Whatever the client still sends is read and ignored until it closes.
                if socket.can_recv() {
                    let _ = socket.recv(|data| (data.len(), ()));
                }
                false
            }
        }
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The answer to a request head: `GET /<n>` → 200 and `n` bytes; anything else → 400.
fn respond(head: &[u8]) -> Exchange {
    let text = String::from_utf8_lossy(head);
    let mut words = text.split_whitespace();
    let len = match (words.next(), words.next()) {
        (Some("GET"), Some(path)) => path
            .strip_prefix('/')
            .and_then(|n| n.parse::<u64>().ok())
            .filter(|&n| n <= MAX_PAYLOAD),
        _ => None,
    };
    match len {
        Some(len) => Exchange::Sending {
            header: format!(
                "HTTP/1.0 200 OK\r\nContent-Type: application/octet-stream\r\nContent-Length: {len}\r\n\r\n"
            )
            .into_bytes(),
            sent: 0,
            len,
        },
        None => Exchange::Sending {
            header: b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n".to_vec(),
            sent: 0,
            len: 0,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_read_as_sizes_or_refused() {
        match respond(b"GET /1000 HTTP/1.1\r\nHost: x") {
            Exchange::Sending { header, len, .. } => {
                assert_eq!(len, 1000);
                assert!(
                    String::from_utf8(header)
                        .unwrap()
                        .contains("Content-Length: 1000")
                );
            }
            other => panic!("{other:?}"),
        }
        for bad in [
            &b"POST /10 HTTP/1.0"[..],
            b"GET /x HTTP/1.0",
            b"GET /99999999999 HTTP/1.0",
        ] {
            match respond(bad) {
                Exchange::Sending { header, len: 0, .. } => {
                    assert!(header.starts_with(b"HTTP/1.0 400"))
                }
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(payload_byte(250), 250);
        assert_eq!(payload_byte(251), 0);
    }
}
