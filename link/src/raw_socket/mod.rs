//! The real bus: an `AF_PACKET` raw socket on a Linux network interface.
//!
//! The socket is bound to one interface and to EtherType 0x88A4, so the kernel hands it
//! EtherCAT frames only, whatever their MAC addresses (slaves may rewrite the source MAC of
//! returning frames).
//!
//! Frames we transmit must never be mistaken for replies. Linux copies outgoing frames only
//! to sockets listening to every EtherType (`ETH_P_ALL`), and never to the socket that sent
//! them, so with this binding they do not come back at all. Two guards keep it that way if
//! the binding ever widens (say to `ETH_P_ALL` to see VLAN-tagged frames): the socket asks
//! the kernel to drop outgoing copies (`PACKET_IGNORE_OUTGOING`, Linux 4.20+), and `recv`
//! skips any frame whose packet type is `PACKET_OUTGOING`, which also covers older kernels.

mod sys;

use std::fmt;
use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, OwnedFd, RawFd};
use std::time::{Duration, Instant};

use super::{Link, Wait, netdev};
use ecat_wire::ethernet::ETHERTYPE_ETHERCAT;

/// How to set up a [`RawSocket`].
///
/// Use struct update syntax for the fields you care about:
/// `RawSocketOptions { busy_poll: true, ..RawSocketOptions::default() }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RawSocketOptions {
    /// Hand frames straight to the driver, skipping the kernel's traffic-control queue
    /// (`PACKET_QDISC_BYPASS`). Lower and steadier latency; frames are dropped instead of
    /// queued when the driver's transmit ring is full. Default: off.
    pub qdisc_bypass: bool,
    /// Wait for frames by spinning on nonblocking reads until the deadline instead of
    /// sleeping in `ppoll(2)`. Lowest latency at the price of a busy CPU core. Default: off.
    pub busy_poll: bool,
    /// Before sleeping in `ppoll(2)` for a frame, spin on nonblocking reads for up to this
    /// long. A reply that comes back within the window is taken without the kernel having
    /// to wake the thread, which on a busy machine costs more than the whole veth round
    /// trip; one that takes longer costs at most this much CPU before the thread sleeps as
    /// without it. Ignored with `busy_poll`, which spins all the way. Default: zero (sleep
    /// at once).
    pub spin: Duration,
    /// Put the interface into promiscuous mode while the socket is open, for peers that send
    /// EtherCAT frames to a unicast address other than ours (masters normally use broadcast,
    /// which needs no promiscuous mode). Default: off.
    pub promiscuous: bool,
    /// Requested size in bytes of the kernel's receive and send buffers for this socket, so
    /// that a burst of frames is not lost while the bus thread is busy. Set with
    /// `SO_*BUFFORCE` when allowed (`CAP_NET_ADMIN`), otherwise capped by
    /// `net.core.{r,w}mem_max`. Default: 1 MiB.
    pub buffer_size: usize,
}

impl Default for RawSocketOptions {
    fn default() -> RawSocketOptions {
        RawSocketOptions {
            qdisc_bypass: false,
            busy_poll: false,
            spin: Duration::ZERO,
            promiscuous: false,
            buffer_size: 1 << 20,
        }
    }
}

/// An `AF_PACKET` raw socket carrying EtherCAT frames on one network interface.
///
/// Opening one needs `CAP_NET_RAW`. The socket belongs to the network namespace of the
/// thread that opened it, wherever it is used afterwards.
pub struct RawSocket {
    fd: OwnedFd,
    interface: String,
    index: u32,
    mac: [u8; 6],
    mtu: u32,
    busy_poll: bool,
    spin: Duration,
}

impl RawSocket {
    /// Opens a raw socket for EtherCAT frames on the interface called `interface`.
    ///
    /// Fails with `InvalidInput` for a name that cannot be an interface name or an interface
    /// that is not Ethernet, `NotFound` if there is no such interface (in this network
    /// namespace), and `PermissionDenied` without `CAP_NET_RAW`. Each error names the
    /// interface and keeps the OS error's text.
    pub fn open(interface: &str, options: RawSocketOptions) -> io::Result<RawSocket> {
        netdev::check_name(interface)?;
        let fd = sys::packet_socket().map_err(|err| {
            if err.kind() == io::ErrorKind::PermissionDenied {
                context(
                    err,
                    format_args!(
                        "opening a raw socket on {interface} needs CAP_NET_RAW (run as root, \
                         or grant it with `setcap cap_net_raw+ep` on the program)"
                    ),
                )
            } else {
                context(err, format_args!("opening a raw socket on {interface}"))
            }
        })?;
        let fd_ref = fd.as_fd();
        let request = netdev::request(interface)?;

        let index = sys::interface_index(fd_ref, request).map_err(|err| {
            if err.raw_os_error() == Some(libc::ENODEV) {
                io::Error::new(
                    io::ErrorKind::NotFound,
                    format!("network interface {interface} not found (in this network namespace)"),
                )
            } else {
                context(
                    err,
                    format_args!("looking up network interface {interface}"),
                )
            }
        })?;
        let (hardware_type, mac) = sys::hardware_address(fd_ref, request)
            .map_err(|err| context(err, format_args!("reading the MAC address of {interface}")))?;
        if hardware_type != libc::ARPHRD_ETHER {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "network interface {interface} is not Ethernet (hardware type {hardware_type}); \
                     EtherCAT needs an Ethernet interface"
                ),
            ));
        }
        let mtu = sys::mtu(fd_ref, request)
            .map_err(|err| context(err, format_args!("reading the MTU of {interface}")))?;

        // A guard against reading our own transmissions as replies (see the module docs).
        // Older kernels refuse the option; `recv` checks the packet type of every frame anyway.
        let _ = sys::set_int_option(fd_ref, libc::SOL_PACKET, libc::PACKET_IGNORE_OUTGOING, 1);
        if options.qdisc_bypass {
            sys::set_int_option(fd_ref, libc::SOL_PACKET, libc::PACKET_QDISC_BYPASS, 1).map_err(
                |err| {
                    context(
                        err,
                        format_args!("enabling PACKET_QDISC_BYPASS on {interface}"),
                    )
                },
            )?;
        }
        set_buffer_size(fd_ref, options.buffer_size).map_err(|err| {
            context(
                err,
                format_args!("sizing the socket buffers on {interface}"),
            )
        })?;
        if options.promiscuous {
            sys::add_promiscuous_membership(fd_ref, index).map_err(|err| {
                context(
                    err,
                    format_args!("enabling promiscuous mode on {interface}"),
                )
            })?;
        }
        // Binding last: only from here on does the socket receive frames.
        sys::bind(fd_ref, index, ETHERTYPE_ETHERCAT)
            .map_err(|err| context(err, format_args!("binding a raw socket to {interface}")))?;

        Ok(RawSocket {
            fd,
            interface: interface.to_owned(),
            // The kernel hands out positive indices and MTUs; a negative one would be a bug
            // there, and 0 is harmless here.
            index: u32::try_from(index).unwrap_or(0),
            mac,
            mtu: u32::try_from(mtu).unwrap_or(0),
            busy_poll: options.busy_poll,
            spin: options.spin,
        })
    }

    /// The name of the interface.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// The kernel's index of the interface.
    pub fn interface_index(&self) -> u32 {
        self.index
    }

    /// The interface's MAC address, for the source address of frames we send.
    pub fn mac_address(&self) -> [u8; 6] {
        self.mac
    }

    /// The interface's MTU: the largest payload after the Ethernet header (1500 normally).
    pub fn mtu(&self) -> u32 {
        self.mtu
    }

    /// Takes one frame if one is queued, skipping any frame we sent ourselves.
    fn try_recv(&self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        loop {
            match sys::recv_frame(self.fd.as_fd(), buf)? {
                sys::Received::Nothing => return Ok(None),
                sys::Received::Frame { packet_type, .. }
                    if packet_type == libc::PACKET_OUTGOING =>
                {
                    continue;
                }
                sys::Received::Frame { len, .. } => return Ok(Some(len.min(buf.len()))),
            }
        }
    }
}

impl Link for RawSocket {
    /// Sends one frame on the interface.
    ///
    /// Fails with `WouldBlock` when the kernel's send queue is full (the frame is not sent:
    /// treat it as lost), and with the OS error if the interface is down or the frame is
    /// longer than the MTU allows.
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        let sent = sys::send(self.fd.as_fd(), frame)?;
        if sent != frame.len() {
            // A packet socket sends whole frames or nothing; anything else is worth knowing.
            return Err(io::Error::other(format!(
                "raw socket on {} sent {sent} of {} bytes",
                self.interface,
                frame.len()
            )));
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        // Until when nonblocking reads are repeated instead of sleeping; taken at the first
        // empty read, so a frame already queued costs no clock read.
        let mut spin_until = None;
        loop {
            if let Some(len) = self.try_recv(buf)? {
                return Ok(Some(len));
            }
            let Wait::Until(deadline) = wait else {
                return Ok(None);
            };
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            let spin_end = *spin_until.get_or_insert(now + self.spin);
            if self.busy_poll || now < spin_end {
                std::hint::spin_loop();
            } else {
                sys::wait_readable(self.fd.as_fd(), deadline - now)?;
            }
        }
    }

    /// The socket itself: readable when a frame is queued (frames we sent ourselves are
    /// never queued, see the module documentation).
    fn wait_fd(&self) -> Option<BorrowedFd<'_>> {
        Some(self.fd.as_fd())
    }
}

/// Waits until one of `fds` (at most two, e.g. the [`Link::wait_fd`]s of a ring's primary
/// and backup ports) is readable or `timeout` has passed. A signal ends the wait early
/// without an error; the caller looks at its links and its deadline again anyway.
pub fn wait_any_readable(fds: &[BorrowedFd<'_>], timeout: Duration) -> io::Result<()> {
    sys::wait_any_readable(fds, timeout).map(|_| ())
}

/// [`wait_any_readable`], saying which of `fds` were readable when it returned (none after
/// a timeout or a signal).
pub fn which_readable(fds: &[BorrowedFd<'_>], timeout: Duration) -> io::Result<[bool; 2]> {
    sys::wait_any_readable(fds, timeout)
}

impl fmt::Debug for RawSocket {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [a, b, c, d, e, g] = self.mac;
        f.debug_struct("RawSocket")
            .field("fd", &self.fd.as_raw_fd())
            .field("interface", &self.interface)
            .field("index", &self.index)
            .field(
                "mac",
                &format_args!("{a:02x}:{b:02x}:{c:02x}:{d:02x}:{e:02x}:{g:02x}"),
            )
            .field("mtu", &self.mtu)
            .field("busy_poll", &self.busy_poll)
            .field("spin", &self.spin)
            .finish()
    }
}

impl AsFd for RawSocket {
    fn as_fd(&self) -> BorrowedFd<'_> {
        self.fd.as_fd()
    }
}

impl AsRawFd for RawSocket {
    fn as_raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}

/// Sizes both socket buffers, forcing past the system limit when we may.
fn set_buffer_size(fd: BorrowedFd<'_>, size: usize) -> io::Result<()> {
    // The kernel doubles the value it is given (for bookkeeping), so ask for half.
    let value = libc::c_int::try_from(size / 2).unwrap_or(libc::c_int::MAX);
    for (forced, capped) in [
        (libc::SO_RCVBUFFORCE, libc::SO_RCVBUF),
        (libc::SO_SNDBUFFORCE, libc::SO_SNDBUF),
    ] {
        if sys::set_int_option(fd, libc::SOL_SOCKET, forced, value).is_err() {
            sys::set_int_option(fd, libc::SOL_SOCKET, capped, value)?;
        }
    }
    Ok(())
}

/// Adds what we were doing to an OS error, keeping its kind and its text.
fn context(err: io::Error, what: fmt::Arguments<'_>) -> io::Error {
    io::Error::new(err.kind(), format!("{what}: {err}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_options_are_the_conservative_ones() {
        let options = RawSocketOptions::default();
        assert!(!options.qdisc_bypass && !options.busy_poll && !options.promiscuous);
        assert_eq!(options.spin, Duration::ZERO);
        assert_eq!(options.buffer_size, 1 << 20);
    }

    #[test]
    fn ethertype_goes_into_socket_addresses_big_endian() {
        assert_eq!(
            sys::network_order(ETHERTYPE_ETHERCAT).to_ne_bytes(),
            [0x88, 0xa4]
        );
    }
}
