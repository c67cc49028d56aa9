//! A Linux TAP interface, opened through `/dev/net/tun` and driven without blocking on the
//! tokio reactor, with what ecatd sets on it: its MAC address, the carrier, the link up,
//! an IPv4 address and membership of a bridge. Everything is an `ioctl` on the TAP's file
//! or on a datagram socket, as `ip` and `brctl` do it; the interface goes away when the
//! [`Tap`] is dropped (it is not persistent).
//!
//! Why not the `tun-tap` crate: it has no carrier control (`TUNSETCARRIER`), which is what
//! tells the host that the slave behind an interface is gone, and its reads block; the few
//! calls needed are written here instead (see `docs/eoe.md`).

use std::io;
use std::net::Ipv4Addr;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};

use tokio::io::Interest;
use tokio::io::unix::AsyncFd;

/// `SIOCBRADDIF` (linux/sockios.h): add an interface to a bridge; not in `libc`.
const SIOCBRADDIF: libc::c_ulong = 0x89a2;

/// The longest interface name Linux takes (`IFNAMSIZ` less the terminating zero).
pub const MAX_NAME_LEN: usize = libc::IFNAMSIZ - 1;

/// One TAP interface.
#[derive(Debug)]
pub struct Tap {
    fd: AsyncFd<OwnedFd>,
    name: String,
}

impl Tap {
    /// Creates the TAP interface `name` (frames without packet information) with `mac`,
    /// its carrier off and its link up, so addresses can be put on it at once.
    pub fn create(name: &str, mac: [u8; 6]) -> io::Result<Tap> {
        let mut request = ifreq(name)?;
        // SAFETY: a NUL-terminated path and plain flags; the result is checked.
        let raw = unsafe {
            libc::open(
                c"/dev/net/tun".as_ptr(),
                libc::O_RDWR | libc::O_NONBLOCK | libc::O_CLOEXEC,
            )
        };
        if raw < 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: `raw` is a file descriptor just opened and owned by nobody else.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        // The flags are a c_short in the request (linux/if_tun.h); both fit.
        request.ifr_ifru.ifru_flags = (libc::IFF_TAP | libc::IFF_NO_PI) as libc::c_short;
        // SAFETY: TUNSETIFF reads and writes one `ifreq`, which `request` is.
        check(unsafe { libc::ioctl(fd.as_raw_fd(), libc::TUNSETIFF, &mut request) })?;
        // SAFETY: `fd` is open and owned by the `AsyncFd` from here on, which returns the
        // same descriptor for as long as it lives.
        let fd = unsafe { AsyncFd::register(fd) }.map_err(io::Error::from)?;
        let tap = Tap {
            fd,
            name: name.to_owned(),
        };
        tap.set_carrier(false)?;
        tap.set_mac(mac)?;
        tap.set_link_up(true)?;
        Ok(tap)
    }

    /// The interface's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Switches the carrier: on while the slave behind the interface can carry frames.
    pub fn set_carrier(&self, on: bool) -> io::Result<()> {
        let value = libc::c_int::from(on);
        // SAFETY: TUNSETCARRIER reads one c_int through the pointer.
        check(unsafe { libc::ioctl(self.fd.as_raw_fd(), libc::TUNSETCARRIER, &value) })
    }

    fn set_mac(&self, mac: [u8; 6]) -> io::Result<()> {
        let mut request = ifreq(&self.name)?;
        // SAFETY: writing plain data into the union's `sockaddr` member.
        unsafe {
            request.ifr_ifru.ifru_hwaddr.sa_family = libc::ARPHRD_ETHER;
            for (slot, byte) in request.ifr_ifru.ifru_hwaddr.sa_data.iter_mut().zip(mac) {
                *slot = byte as libc::c_char;
            }
        }
        socket_ioctl(libc::SIOCSIFHWADDR, &mut request)
    }

    /// Sets the link (administratively) up or down.
    pub fn set_link_up(&self, up: bool) -> io::Result<()> {
        set_link_up(&self.name, up)
    }

    /// Puts the IPv4 address `address/prefix` on the interface.
    pub fn set_address(&self, address: Ipv4Addr, prefix: u8) -> io::Result<()> {
        let mut request = ifreq(&self.name)?;
        request.ifr_ifru.ifru_addr = sockaddr_in(address);
        socket_ioctl(libc::SIOCSIFADDR, &mut request)?;
        let mask = u32::MAX
            .checked_shl(32 - u32::from(prefix.min(32)))
            .unwrap_or(0);
        let mut request = ifreq(&self.name)?;
        request.ifr_ifru.ifru_netmask = sockaddr_in(Ipv4Addr::from(mask));
        socket_ioctl(libc::SIOCSIFNETMASK, &mut request)
    }

    /// Adds the interface to the existing bridge `bridge`.
    pub fn join_bridge(&self, bridge: &str) -> io::Result<()> {
        let index = interface_index(&self.name)?;
        let mut request = ifreq(bridge)?;
        request.ifr_ifru.ifru_ifindex = index;
        socket_ioctl(SIOCBRADDIF, &mut request)
    }

    /// Reads one frame (destination MAC first, no FCS) into `buf`.
    pub async fn read(&self, buf: &mut [u8]) -> io::Result<usize> {
        self.fd
            .async_io(Interest::READABLE, |fd| {
                // SAFETY: reading at most `buf.len()` bytes into `buf`.
                let n = unsafe { libc::read(fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
                usize::try_from(n).map_err(|_| io::Error::last_os_error())
            })
            .await
    }

    /// Writes one frame.
    pub async fn write(&self, frame: &[u8]) -> io::Result<()> {
        self.fd
            .async_io(Interest::WRITABLE, |fd| {
                // SAFETY: writing `frame.len()` bytes from `frame`.
                let n = unsafe { libc::write(fd.as_raw_fd(), frame.as_ptr().cast(), frame.len()) };
                usize::try_from(n).map_err(|_| io::Error::last_os_error())
            })
            .await
            .map(drop)
    }
}

fn check(result: libc::c_int) -> io::Result<()> {
    if result < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(())
    }
}

/// An `ifreq` naming `name`, the rest zero.
fn ifreq(name: &str) -> io::Result<libc::ifreq> {
    if name.is_empty() || name.len() > MAX_NAME_LEN || name.bytes().any(|b| b == 0 || b == b'/') {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("bad interface name {name:?}"),
        ));
    }
    // SAFETY: `ifreq` is plain data; all zeroes is a valid value.
    let mut request: libc::ifreq = unsafe { std::mem::zeroed() };
    for (slot, byte) in request.ifr_name.iter_mut().zip(name.bytes()) {
        *slot = byte as libc::c_char;
    }
    Ok(request)
}

fn sockaddr_in(address: Ipv4Addr) -> libc::sockaddr {
    let inet = libc::sockaddr_in {
        sin_family: libc::AF_INET as libc::sa_family_t,
        sin_port: 0,
        sin_addr: libc::in_addr {
            s_addr: u32::from_ne_bytes(address.octets()),
        },
        sin_zero: [0; 8],
    };
    // SAFETY: `sockaddr_in` and `sockaddr` have the same size (16 bytes), and the kernel
    // reads the address as the family says.
    unsafe { std::mem::transmute::<libc::sockaddr_in, libc::sockaddr>(inet) }
}

/// A datagram socket for the interface ioctls, closed on drop.
fn control_socket() -> io::Result<OwnedFd> {
    // SAFETY: plain arguments; the result is checked.
    let raw: RawFd =
        unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM | libc::SOCK_CLOEXEC, 0) };
    if raw < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: a descriptor just opened and owned by nobody else.
    Ok(unsafe { OwnedFd::from_raw_fd(raw) })
}

fn socket_ioctl(request: libc::c_ulong, ifr: &mut libc::ifreq) -> io::Result<()> {
    let socket = control_socket()?;
    // SAFETY: every request used here reads or writes one `ifreq`.
    check(unsafe { libc::ioctl(socket.as_raw_fd(), request, std::ptr::from_mut(ifr)) })
}

fn interface_index(name: &str) -> io::Result<libc::c_int> {
    let mut request = ifreq(name)?;
    socket_ioctl(libc::SIOCGIFINDEX, &mut request)?;
    // SAFETY: SIOCGIFINDEX filled the index member.
    Ok(unsafe { request.ifr_ifru.ifru_ifindex })
}

/// Sets the link of interface `name` up or down, keeping its other flags.
pub fn set_link_up(name: &str, up: bool) -> io::Result<()> {
    let mut request = ifreq(name)?;
    socket_ioctl(libc::SIOCGIFFLAGS, &mut request)?;
    // SAFETY: SIOCGIFFLAGS filled the flags member.
    let mut flags = unsafe { request.ifr_ifru.ifru_flags };
    let bit = libc::IFF_UP as libc::c_short;
    if up {
        flags |= bit;
    } else {
        flags &= !bit;
    }
    request.ifr_ifru.ifru_flags = flags;
    socket_ioctl(libc::SIOCSIFFLAGS, &mut request)
}

/// The MAC address of interface `name` from sysfs, if it has one.
pub fn mac_of(name: &str) -> Option<[u8; 6]> {
    let text = std::fs::read_to_string(format!("/sys/class/net/{name}/address")).ok()?;
    crate::eoe::config::parse_mac(text.trim()).ok()
}
