//! The kernel's network-device controls: what a valid interface name is, the `struct ifreq`
//! every interface `ioctl` takes, and the few settings ecatd and its simulator make on an
//! interface (link up, MAC, IPv4 address, bridge membership, a new TAP).
//!
//! One module for all of them because three places need the same calls: the raw socket
//! here (the interface index and hardware address of the bus NIC), ecatd's EoE interfaces
//! (`server/src/eoe/tap.rs`) and the simulator's EoE bridge (`ecat-sim --eoe-tap`). Every
//! setting is an `ioctl` on a short-lived datagram socket, as `ip` and `brctl` do it, so no
//! process is started and no netlink crate is needed for these five requests.

use std::io;
use std::net::Ipv4Addr;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};

/// The longest interface name Linux takes (`IFNAMSIZ` less the terminating zero).
pub const MAX_NAME_LEN: usize = libc::IFNAMSIZ - 1;

/// `SIOCBRADDIF` (linux/sockios.h): add an interface to a bridge; not in `libc`.
const SIOCBRADDIF: libc::c_ulong = 0x89a2;

/// Refuses names the kernel could not hold in `ifreq` (at most 15 bytes, no NUL) or that no
/// interface can have (empty, or containing `/` or whitespace), before any system call.
pub fn check_name(name: &str) -> io::Result<()> {
    let valid = !name.is_empty()
        && name.len() <= MAX_NAME_LEN
        && !name
            .bytes()
            .any(|byte| byte == 0 || byte == b'/' || byte.is_ascii_whitespace());
    if valid {
        Ok(())
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{name:?} is not a valid network interface name (1 to {MAX_NAME_LEN} bytes, \
                 no '/', whitespace or NUL)"
            ),
        ))
    }
}

/// An interface request (`struct ifreq`) naming `name`, the rest zero.
pub fn request(name: &str) -> io::Result<libc::ifreq> {
    check_name(name)?;
    // SAFETY: `ifreq` is a C struct of byte arrays and a union of integers, socket addresses
    // and a pointer; all-zero bytes are a valid value for each of them.
    let mut request: libc::ifreq = unsafe { std::mem::zeroed() };
    for (slot, byte) in request.ifr_name.iter_mut().zip(name.bytes()) {
        *slot = byte as libc::c_char;
    }
    Ok(request)
}

/// Runs the interface `ioctl` `command` on `name`, with an `ifreq` that `fill` completed,
/// on a datagram socket of its own; returns the `ifreq` as the kernel left it.
pub fn control(
    name: &str,
    command: libc::c_ulong,
    fill: impl FnOnce(&mut libc::ifreq),
) -> io::Result<libc::ifreq> {
    let mut request = request(name)?;
    fill(&mut request);
    // SAFETY: plain arguments; the result is checked.
    let raw = unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM | libc::SOCK_CLOEXEC, 0) };
    if raw < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: a descriptor just opened, owned by nobody else (closed on return).
    let socket = unsafe { OwnedFd::from_raw_fd(raw) };
    // SAFETY: every command used with this function reads or writes one `ifreq`, which
    // `request` is, exclusively borrowed for the call.
    let result = unsafe {
        libc::ioctl(
            socket.as_raw_fd(),
            command as _,
            std::ptr::from_mut(&mut request),
        )
    };
    if result < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(request)
}

/// The interface index of `name` (`SIOCGIFINDEX`).
pub fn index(name: &str) -> io::Result<libc::c_int> {
    let request = control(name, libc::SIOCGIFINDEX, |_| {})?;
    // SAFETY: SIOCGIFINDEX succeeded, so the kernel stored the index in this member.
    Ok(unsafe { request.ifr_ifru.ifru_ifindex })
}

/// Sets the link of `name` (administratively) up or down, keeping its other flags.
pub fn set_link_up(name: &str, up: bool) -> io::Result<()> {
    let current = control(name, libc::SIOCGIFFLAGS, |_| {})?;
    // SAFETY: SIOCGIFFLAGS succeeded, so the kernel stored the flags in this member.
    let mut flags = unsafe { current.ifr_ifru.ifru_flags };
    let bit = libc::IFF_UP as libc::c_short;
    if up {
        flags |= bit;
    } else {
        flags &= !bit;
    }
    control(name, libc::SIOCSIFFLAGS, |r| r.ifr_ifru.ifru_flags = flags).map(drop)
}

/// Sets the Ethernet (MAC) address of `name`.
pub fn set_mac(name: &str, mac: [u8; 6]) -> io::Result<()> {
    control(name, libc::SIOCSIFHWADDR, |r| {
        // SAFETY: writing plain data into the union's `sockaddr` member.
        let hw = unsafe { &mut r.ifr_ifru.ifru_hwaddr };
        hw.sa_family = libc::ARPHRD_ETHER;
        for (slot, byte) in hw.sa_data.iter_mut().zip(mac) {
            *slot = byte as libc::c_char;
        }
    })
    .map(drop)
}

/// Puts the IPv4 `address` on `name`, and `mask` when given (the kernel derives a classful
/// mask from the address otherwise).
pub fn set_ipv4(name: &str, address: Ipv4Addr, mask: Option<Ipv4Addr>) -> io::Result<()> {
    control(name, libc::SIOCSIFADDR, |r| {
        r.ifr_ifru.ifru_addr = ipv4_sockaddr(address);
    })?;
    if let Some(mask) = mask {
        control(name, libc::SIOCSIFNETMASK, |r| {
            r.ifr_ifru.ifru_netmask = ipv4_sockaddr(mask);
        })?;
    }
    Ok(())
}

/// The netmask of a prefix length (`24` -> 255.255.255.0); lengths over 32 count as 32.
pub fn prefix_mask(prefix: u8) -> Ipv4Addr {
    let bits = u32::from(prefix.min(32));
    Ipv4Addr::from(u32::MAX.checked_shl(32 - bits).unwrap_or(0))
}

/// Adds `name` to the existing Linux bridge `bridge` (`SIOCBRADDIF`).
pub fn join_bridge(name: &str, bridge: &str) -> io::Result<()> {
    let index = index(name)?;
    control(bridge, SIOCBRADDIF, |r| r.ifr_ifru.ifru_ifindex = index).map(drop)
}

/// `/dev/net/tun` attached to a new TAP interface `name` carrying bare Ethernet frames (no
/// packet information header); the interface goes away when the descriptor is closed.
pub fn open_tap(name: &str, nonblocking: bool) -> io::Result<OwnedFd> {
    let mut request = request(name)?;
    let mut flags = libc::O_RDWR | libc::O_CLOEXEC;
    if nonblocking {
        flags |= libc::O_NONBLOCK;
    }
    // SAFETY: a NUL-terminated path and plain flags; the result is checked.
    let raw = unsafe { libc::open(c"/dev/net/tun".as_ptr(), flags) };
    if raw < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: a descriptor just opened, owned by nobody else.
    let tun = unsafe { OwnedFd::from_raw_fd(raw) };
    // The flags are a c_short in the request (linux/if_tun.h); both fit.
    request.ifr_ifru.ifru_flags = (libc::IFF_TAP | libc::IFF_NO_PI) as libc::c_short;
    // SAFETY: TUNSETIFF reads and writes one `ifreq`, which `request` is.
    if unsafe { libc::ioctl(tun.as_raw_fd(), libc::TUNSETIFF, &mut request) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(tun)
}

/// An IPv4 address as the `sockaddr` (laid out as `sockaddr_in`) the interface controls take.
pub fn ipv4_sockaddr(address: Ipv4Addr) -> libc::sockaddr {
    // SAFETY: all zeroes is a valid `sockaddr`.
    let mut out: libc::sockaddr = unsafe { std::mem::zeroed() };
    out.sa_family = libc::AF_INET as libc::sa_family_t;
    // sockaddr_in: the port (2 bytes, left 0), then the address in network order.
    for (slot, byte) in out.sa_data[2..6].iter_mut().zip(address.octets()) {
        *slot = byte as libc::c_char;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interface_names_the_kernel_cannot_hold_are_refused_before_any_system_call() {
        for bad in ["", "sixteen-bytes-xx", "a/b", "a b", "tab\t", "nul\0"] {
            let err = request(bad).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{bad:?}");
            assert_eq!(
                control(bad, libc::SIOCGIFINDEX, |_| {}).unwrap_err().kind(),
                err.kind()
            );
        }
        for good in ["eth0", "enp3s0f1", "veth-ecat.100", "fifteen-bytes-x"] {
            let request = request(good).unwrap();
            let name: Vec<u8> = request.ifr_name.iter().map(|&c| c as u8).collect();
            assert_eq!(&name[..good.len()], good.as_bytes());
            assert_eq!(name[good.len()], 0, "NUL-terminated");
        }
    }

    #[test]
    fn an_address_is_laid_out_as_sockaddr_in() {
        let sa = ipv4_sockaddr(Ipv4Addr::new(10, 78, 0, 2));
        assert_eq!(sa.sa_family, libc::AF_INET as libc::sa_family_t);
        let bytes: Vec<u8> = sa.sa_data[..6].iter().map(|&b| b as u8).collect();
        assert_eq!(bytes, [0, 0, 10, 78, 0, 2]);
    }

    #[test]
    fn prefix_lengths_become_masks() {
        assert_eq!(prefix_mask(0), Ipv4Addr::UNSPECIFIED);
        assert_eq!(prefix_mask(24), Ipv4Addr::new(255, 255, 255, 0));
        assert_eq!(prefix_mask(20), Ipv4Addr::new(255, 255, 240, 0));
        assert_eq!(prefix_mask(32), Ipv4Addr::BROADCAST);
        assert_eq!(prefix_mask(40), Ipv4Addr::BROADCAST);
    }

    #[test]
    fn a_missing_interface_is_an_os_error_not_a_panic() {
        let err = index("ecat-none-9z").unwrap_err();
        assert_eq!(err.raw_os_error(), Some(libc::ENODEV));
    }
}
