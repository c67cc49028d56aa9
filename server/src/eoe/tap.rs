//! A Linux TAP interface, opened through `/dev/net/tun` and driven without blocking on the
//! tokio reactor, with what ecatd sets on it: its MAC address, the carrier, the link up,
//! an IPv4 address and membership of a bridge. The carrier is an `ioctl` on the TAP's file;
//! the rest are master-core's network-device controls (`master_core::link::netdev`, shared
//! with the simulator's EoE bridge); the interface goes away when the [`Tap`] is dropped (it
//! is not persistent).
//!
//! Why not the `tun-tap` crate: it has no carrier control (`TUNSETCARRIER`), which is what
//! tells the host that the slave behind an interface is gone, and its reads block; the few
//! calls needed are written in `netdev` instead (see `docs/eoe.md`).

use std::io;
use std::net::Ipv4Addr;
use std::os::fd::{AsRawFd, OwnedFd};

use master_core::link::netdev;
use tokio::io::Interest;
use tokio::io::unix::AsyncFd;

/// The longest interface name Linux takes (`IFNAMSIZ` less the terminating zero).
pub const MAX_NAME_LEN: usize = netdev::MAX_NAME_LEN;

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
        let fd = netdev::open_tap(name, true)?;
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
        if unsafe { libc::ioctl(self.fd.as_raw_fd(), libc::TUNSETCARRIER, &value) } < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    fn set_mac(&self, mac: [u8; 6]) -> io::Result<()> {
        netdev::set_mac(&self.name, mac)
    }

    /// Sets the link (administratively) up or down.
    pub fn set_link_up(&self, up: bool) -> io::Result<()> {
        netdev::set_link_up(&self.name, up)
    }

    /// Puts the IPv4 address `address/prefix` on the interface.
    pub fn set_address(&self, address: Ipv4Addr, prefix: u8) -> io::Result<()> {
        netdev::set_ipv4(&self.name, address, Some(netdev::prefix_mask(prefix)))
    }

    /// Adds the interface to the existing bridge `bridge`.
    pub fn join_bridge(&self, bridge: &str) -> io::Result<()> {
        netdev::join_bridge(&self.name, bridge)
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

/// The MAC address of interface `name` from sysfs, if it has one.
pub fn mac_of(name: &str) -> Option<[u8; 6]> {
    let text = std::fs::read_to_string(format!("/sys/class/net/{name}/address")).ok()?;
    crate::input::ip::parse_mac(text.trim()).ok()
}
