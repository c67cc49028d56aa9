//! Binding the UDP socket: the wanted port, or a free one if it is taken.

use std::io;
use std::net::{SocketAddr, UdpSocket};

/// Binds `ip:port`; if that port is in use and `fallback` is set, binds a port the system
/// chooses. Returns the socket and whether it fell back.
pub(crate) fn bind(
    ip: std::net::IpAddr,
    port: u16,
    fallback: bool,
) -> io::Result<(UdpSocket, bool)> {
    match UdpSocket::bind(SocketAddr::new(ip, port)) {
        Ok(socket) => Ok((socket, false)),
        Err(err) if fallback && err.kind() == io::ErrorKind::AddrInUse => {
            let socket = UdpSocket::bind(SocketAddr::new(ip, 0))?;
            Ok((socket, true))
        }
        Err(err) => Err(err),
    }
}
