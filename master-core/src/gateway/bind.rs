//! Binding the sockets: UDP on the wanted port, or a free one if it is taken; with TCP on,
//! a TCP listener on the same port number too.
//!
//! With several receive workers, each gets its own UDP socket on the same address and port
//! (`SO_REUSEPORT`): the kernel hashes every datagram to one socket of the group by the
//! client's address and port, so one client's datagrams always reach the same worker, in
//! the order they came. Since a second program of the same user could join such a group
//! and take part of the traffic, a wanted port is first tried with a plain socket: a port
//! that anyone holds (a group included) counts as taken, as with a single socket.

use std::io;
use std::net::{IpAddr, SocketAddr, TcpListener, UdpSocket};

use socket2::{Domain, Protocol, Socket, Type};

/// Free ports tried for a UDP + TCP pair before giving up (a port free for UDP may be
/// taken for TCP).
const PAIR_ATTEMPTS: usize = 16;

/// The sockets bound.
pub(crate) struct Bound {
    /// One per receive worker, all on the same address and port (at least one).
    pub udp: Vec<UdpSocket>,
    pub tcp: Option<TcpListener>,
    /// Whether the wanted port was taken and another was bound.
    pub fell_back: bool,
}

/// Binds `workers` UDP sockets (and TCP if `tcp`) at `ip:port`; if that port is in use and
/// `fallback` is set, binds a port the system chooses, free for both. With port 0 (any), a
/// port the system gave for UDP but another program holds for TCP is simply tried again.
pub(crate) fn bind(
    ip: IpAddr,
    port: u16,
    fallback: bool,
    tcp: bool,
    workers: usize,
) -> io::Result<Bound> {
    let workers = workers.max(1);
    match bind_pair(ip, port, tcp, workers) {
        Ok((udp, tcp)) => Ok(Bound {
            udp,
            tcp,
            fell_back: false,
        }),
        Err(err) if (fallback || port == 0) && err.kind() == io::ErrorKind::AddrInUse => {
            let mut last = err;
            for _ in 0..PAIR_ATTEMPTS {
                match bind_pair(ip, 0, tcp, workers) {
                    Ok((udp, tcp)) => {
                        return Ok(Bound {
                            udp,
                            tcp,
                            fell_back: port != 0,
                        });
                    }
                    Err(err) if err.kind() == io::ErrorKind::AddrInUse => last = err,
                    Err(err) => return Err(err),
                }
            }
            Err(last)
        }
        Err(err) => Err(err),
    }
}

/// UDP at `ip:port` (0: any), then TCP at the port UDP got.
fn bind_pair(
    ip: IpAddr,
    port: u16,
    tcp: bool,
    workers: usize,
) -> io::Result<(Vec<UdpSocket>, Option<TcpListener>)> {
    let udp = bind_udp(SocketAddr::new(ip, port), workers)?;
    if !tcp {
        return Ok((udp, None));
    }
    let bound = udp[0].local_addr()?;
    let listener = TcpListener::bind(bound)?;
    Ok((udp, Some(listener)))
}

/// `workers` UDP sockets on `addr` (port 0: the one the first gets).
fn bind_udp(addr: SocketAddr, workers: usize) -> io::Result<Vec<UdpSocket>> {
    if workers == 1 {
        return Ok(vec![UdpSocket::bind(addr)?]);
    }
    if addr.port() != 0 {
        // Taken by anyone, a reuse group of this user included? Then it is taken for us.
        drop(UdpSocket::bind(addr)?);
    }
    let first = reuse_port_socket(addr)?;
    let addr = first.local_addr()?;
    let mut sockets = vec![first];
    for _ in 1..workers {
        sockets.push(reuse_port_socket(addr)?);
    }
    Ok(sockets)
}

fn reuse_port_socket(addr: SocketAddr) -> io::Result<UdpSocket> {
    let socket = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(Protocol::UDP))?;
    socket.set_reuse_port(true)?;
    socket.bind(&addr.into())?;
    Ok(socket.into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::Ipv4Addr;

    const LOOPBACK: IpAddr = IpAddr::V4(Ipv4Addr::LOCALHOST);

    #[test]
    fn workers_share_one_port_and_a_held_port_counts_as_taken() {
        let group = bind(LOOPBACK, 0, false, true, 3).unwrap();
        assert_eq!(group.udp.len(), 3);
        let port = group.udp[0].local_addr().unwrap().port();
        assert!(
            group
                .udp
                .iter()
                .all(|s| s.local_addr().unwrap().port() == port)
        );
        assert_eq!(
            group.tcp.as_ref().unwrap().local_addr().unwrap().port(),
            port
        );
        // A second group on the same port would share the traffic: refused, or moved.
        let err = bind(LOOPBACK, port, false, false, 2).err().unwrap();
        assert_eq!(err.kind(), io::ErrorKind::AddrInUse);
        let moved = bind(LOOPBACK, port, true, false, 2).unwrap();
        assert!(moved.fell_back);
        assert_ne!(moved.udp[0].local_addr().unwrap().port(), port);
    }
}
