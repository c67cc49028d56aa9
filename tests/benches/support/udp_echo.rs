//! A UDP echo on loopback: the gateway's transport with nothing behind it, as one worker of
//! ecatd's gateway receives and answers. The floor and ceiling rows of the benches measure
//! against it.

/// The name of the echo's thread, for its CPU time in `/proc/self/task/*/schedstat`.
pub const THREAD: &str = "udp-echo";

/// Starts a thread that sends every datagram back to its sender at once; its address. The
/// thread ends with the process (or when a reply cannot be sent).
pub fn start() -> std::net::SocketAddr {
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").expect("echo socket");
    let addr = socket.local_addr().expect("echo address");
    std::thread::Builder::new()
        .name(THREAD.into())
        .spawn(move || {
            let mut buf = [0u8; 2048];
            while let Ok((len, from)) = socket.recv_from(&mut buf) {
                if socket.send_to(&buf[..len], from).is_err() {
                    break;
                }
            }
        })
        .expect("echo thread");
    addr
}
