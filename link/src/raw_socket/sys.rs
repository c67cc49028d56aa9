//! Safe wrappers around the few system calls a packet socket needs.
//!
//! Every `unsafe` block of the raw socket lives here, each next to the one call it makes, so
//! the socket logic in `mod.rs` reads as plain Rust. Errors are the OS error (`errno`) as
//! `io::Error`; the caller adds the context it knows.

use std::ffi::c_int;
use std::io;
use std::mem;
use std::os::fd::{AsRawFd, BorrowedFd, FromRawFd, OwnedFd};
use std::time::Duration;

/// `htons`: EtherTypes go into socket addresses in network byte order.
pub(super) fn network_order(value: u16) -> u16 {
    value.to_be()
}

/// Opens an `AF_PACKET`/`SOCK_RAW` socket, nonblocking and close-on-exec.
///
/// The protocol is 0 so that the socket receives nothing at all until it is bound to one
/// interface and EtherType; otherwise frames from every interface would queue up meanwhile.
pub(super) fn packet_socket() -> io::Result<OwnedFd> {
    // SAFETY: socket(2) takes only integer arguments and returns a new descriptor or -1.
    let fd = unsafe {
        libc::socket(
            libc::AF_PACKET,
            libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            0,
        )
    };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `fd` was just returned by socket(2), is open, and nothing else owns it.
    Ok(unsafe { OwnedFd::from_raw_fd(fd) })
}

/// Runs one `SIOCGIF*` query that fills in `request`.
fn interface_ioctl(
    fd: BorrowedFd<'_>,
    command: libc::c_ulong,
    request: &mut libc::ifreq,
) -> io::Result<()> {
    // SAFETY: the SIOCGIF* queries used here read the NUL-terminated name in `request` and
    // write at most one `ifreq` back into it; `request` is a valid, exclusive `ifreq`.
    let result = unsafe {
        libc::ioctl(
            fd.as_raw_fd(),
            command as _,
            std::ptr::from_mut::<libc::ifreq>(request),
        )
    };
    if result < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// The interface index of the interface named in `request` (`SIOCGIFINDEX`).
pub(super) fn interface_index(fd: BorrowedFd<'_>, mut request: libc::ifreq) -> io::Result<c_int> {
    interface_ioctl(fd, libc::SIOCGIFINDEX, &mut request)?;
    // SAFETY: SIOCGIFINDEX succeeded, so the kernel stored the index in this union member.
    Ok(unsafe { request.ifr_ifru.ifru_ifindex })
}

/// The hardware type (`ARPHRD_*`) and address of the interface (`SIOCGIFHWADDR`).
pub(super) fn hardware_address(
    fd: BorrowedFd<'_>,
    mut request: libc::ifreq,
) -> io::Result<(u16, [u8; 6])> {
    interface_ioctl(fd, libc::SIOCGIFHWADDR, &mut request)?;
    // SAFETY: SIOCGIFHWADDR succeeded, so the kernel stored a `sockaddr` in this member.
    let address = unsafe { request.ifr_ifru.ifru_hwaddr };
    let mut mac = [0u8; 6];
    for (byte, raw) in mac.iter_mut().zip(address.sa_data) {
        *byte = raw as u8;
    }
    Ok((address.sa_family, mac))
}

/// The MTU of the interface (`SIOCGIFMTU`).
pub(super) fn mtu(fd: BorrowedFd<'_>, mut request: libc::ifreq) -> io::Result<c_int> {
    interface_ioctl(fd, libc::SIOCGIFMTU, &mut request)?;
    // SAFETY: SIOCGIFMTU succeeded, so the kernel stored the MTU in this union member.
    Ok(unsafe { request.ifr_ifru.ifru_mtu })
}

/// Sets a socket option whose value is a C struct or integer.
fn set_option<T>(fd: BorrowedFd<'_>, level: c_int, name: c_int, value: &T) -> io::Result<()> {
    let len = libc::socklen_t::try_from(mem::size_of::<T>())
        .map_err(|_| io::Error::from(io::ErrorKind::InvalidInput))?;
    // SAFETY: `value` points to `len` readable bytes for the duration of the call; the
    // kernel only reads them.
    let result = unsafe {
        libc::setsockopt(
            fd.as_raw_fd(),
            level,
            name,
            std::ptr::from_ref::<T>(value).cast(),
            len,
        )
    };
    if result < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Sets an integer socket option.
pub(super) fn set_int_option(
    fd: BorrowedFd<'_>,
    level: c_int,
    name: c_int,
    value: c_int,
) -> io::Result<()> {
    set_option(fd, level, name, &value)
}

/// Puts the interface into promiscuous mode for as long as this socket is open.
pub(super) fn add_promiscuous_membership(fd: BorrowedFd<'_>, ifindex: c_int) -> io::Result<()> {
    // SAFETY: `packet_mreq` is plain integers and a byte array; all-zero is valid.
    let mut request: libc::packet_mreq = unsafe { mem::zeroed() };
    request.mr_ifindex = ifindex;
    request.mr_type = libc::PACKET_MR_PROMISC as libc::c_ushort;
    set_option(fd, libc::SOL_PACKET, libc::PACKET_ADD_MEMBERSHIP, &request)
}

/// Binds the socket to one interface and one EtherType (given in host byte order).
pub(super) fn bind(fd: BorrowedFd<'_>, ifindex: c_int, ethertype: u16) -> io::Result<()> {
    // SAFETY: `sockaddr_ll` is plain integers and a byte array; all-zero is valid.
    let mut address: libc::sockaddr_ll = unsafe { mem::zeroed() };
    address.sll_family = libc::AF_PACKET as libc::c_ushort;
    address.sll_protocol = network_order(ethertype);
    address.sll_ifindex = ifindex;
    let len = mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
    // SAFETY: `address` is a valid `sockaddr_ll` of `len` bytes, only read by the kernel.
    let result = unsafe {
        libc::bind(
            fd.as_raw_fd(),
            std::ptr::from_ref(&address).cast::<libc::sockaddr>(),
            len,
        )
    };
    if result < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

/// Sends one complete frame; retries if a signal interrupts the call.
pub(super) fn send(fd: BorrowedFd<'_>, frame: &[u8]) -> io::Result<usize> {
    loop {
        // SAFETY: `frame` is valid for reading `frame.len()` bytes during the call.
        let sent = unsafe { libc::send(fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0) };
        if let Ok(sent) = usize::try_from(sent) {
            return Ok(sent);
        }
        let err = io::Error::last_os_error();
        if err.kind() != io::ErrorKind::Interrupted {
            return Err(err);
        }
    }
}

/// What `recv_frame` found in the socket.
pub(super) enum Received {
    /// Nothing is queued.
    Nothing,
    /// A frame: its full length on the wire (it may be longer than the buffer) and its
    /// packet type (`PACKET_HOST`, `PACKET_OUTGOING`, ...).
    Frame { len: usize, packet_type: u8 },
}

/// Takes one frame from a nonblocking packet socket without waiting.
pub(super) fn recv_frame(fd: BorrowedFd<'_>, buf: &mut [u8]) -> io::Result<Received> {
    loop {
        // SAFETY: `sockaddr_ll` is plain integers and a byte array; all-zero is valid.
        let mut from: libc::sockaddr_ll = unsafe { mem::zeroed() };
        let mut from_len = mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
        // SAFETY: `buf` is valid for writing `buf.len()` bytes, and `from`/`from_len` describe
        // a writable `sockaddr_ll`, for the duration of the call. MSG_TRUNC makes the kernel
        // report the frame's real length but still write no more than `buf.len()` bytes.
        let len = unsafe {
            libc::recvfrom(
                fd.as_raw_fd(),
                buf.as_mut_ptr().cast(),
                buf.len(),
                libc::MSG_TRUNC,
                std::ptr::from_mut(&mut from).cast::<libc::sockaddr>(),
                &mut from_len,
            )
        };
        if let Ok(len) = usize::try_from(len) {
            return Ok(Received::Frame {
                len,
                packet_type: from.sll_pkttype,
            });
        }
        let err = io::Error::last_os_error();
        match err.kind() {
            io::ErrorKind::Interrupted => continue,
            io::ErrorKind::WouldBlock => return Ok(Received::Nothing),
            _ => return Err(err),
        }
    }
}

/// Waits until the socket is readable or `timeout` has passed.
///
/// Returns early, without error, if a signal interrupts the wait: the caller re-checks the
/// socket and its deadline anyway.
pub(super) fn wait_readable(fd: BorrowedFd<'_>, timeout: Duration) -> io::Result<()> {
    wait_any_readable(&[fd], timeout).map(|_| ())
}

/// Waits until one of `fds` is readable or `timeout` has passed (early, without error, on
/// a signal); says which were readable (none after a timeout or a signal).
pub(crate) fn wait_any_readable(
    fds: &[BorrowedFd<'_>],
    timeout: Duration,
) -> io::Result<[bool; 2]> {
    // Two links at most wait together (a ring's ports); more is a caller's mistake.
    let mut poll_fds = [libc::pollfd {
        fd: -1,
        events: libc::POLLIN,
        revents: 0,
    }; 2];
    if fds.len() > poll_fds.len() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "at most two links wait together",
        ));
    }
    for (slot, fd) in poll_fds.iter_mut().zip(fds) {
        slot.fd = fd.as_raw_fd();
    }
    // ppoll takes nanoseconds; poll's milliseconds would make a 100 µs timeout either 0 (a
    // busy loop) or 1 ms (late). Seconds saturate far beyond any real deadline.
    let timeout = libc::timespec {
        tv_sec: libc::time_t::try_from(timeout.as_secs()).unwrap_or(libc::time_t::MAX),
        // Below 10^9, so it fits a C long everywhere.
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: `poll_fds` holds `fds.len()` valid `pollfd`s and `timeout` is a valid
    // `timespec`, both alive for the call; a null signal mask leaves the thread's mask
    // unchanged.
    let result = unsafe {
        libc::ppoll(
            poll_fds.as_mut_ptr(),
            fds.len() as libc::nfds_t,
            &timeout,
            std::ptr::null(),
        )
    };
    if result < 0 {
        let err = io::Error::last_os_error();
        if err.kind() != io::ErrorKind::Interrupted {
            return Err(err);
        }
        return Ok([false; 2]);
    }
    // An error or hang-up counts as readable: the read that follows reports it.
    Ok(poll_fds.map(|p| p.fd >= 0 && p.revents != 0))
}
