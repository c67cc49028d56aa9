//! Binding the sockets: UDP on the wanted port, or a free one if it is taken; with TCP on,
//! a TCP listener on the same port number too.

use std::io;
use std::net::{IpAddr, SocketAddr, TcpListener, UdpSocket};

/// Free ports tried for a UDP + TCP pair before giving up (a port free for UDP may be
/// taken for TCP).
const PAIR_ATTEMPTS: usize = 16;

/// The sockets bound.
pub(crate) struct Bound {
    pub udp: UdpSocket,
    pub tcp: Option<TcpListener>,
    /// Whether the wanted port was taken and another was bound.
    pub fell_back: bool,
}

/// Binds UDP (and TCP if `tcp`) at `ip:port`; if that port is in use and `fallback` is
/// set, binds a port the system chooses, free for both.
pub(crate) fn bind(ip: IpAddr, port: u16, fallback: bool, tcp: bool) -> io::Result<Bound> {
    match bind_pair(ip, port, tcp) {
        Ok((udp, tcp)) => Ok(Bound {
            udp,
            tcp,
            fell_back: false,
        }),
        Err(err) if fallback && err.kind() == io::ErrorKind::AddrInUse => {
            let mut last = err;
            for _ in 0..PAIR_ATTEMPTS {
                match bind_pair(ip, 0, tcp) {
                    Ok((udp, tcp)) => {
                        return Ok(Bound {
                            udp,
                            tcp,
                            fell_back: true,
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
fn bind_pair(ip: IpAddr, port: u16, tcp: bool) -> io::Result<(UdpSocket, Option<TcpListener>)> {
    let udp = UdpSocket::bind(SocketAddr::new(ip, port))?;
    if !tcp {
        return Ok((udp, None));
    }
    let bound = udp.local_addr()?;
    let listener = TcpListener::bind(bound)?;
    Ok((udp, Some(listener)))
}
