//! `--eoe-tap NAME`: an EoE slave's Ethernet side bridged to a TAP interface in ecat-sim's
//! own network namespace, so the Linux stack there is the device behind the slave (and
//! `iperf3 -s` or any server can run behind it).
//!
//! Two threads beside the frame loop, which they meet only through the slave's
//! [`HostPort`] (bounded queues, drops counted):
//! - the reader takes each frame the kernel sends out of the TAP and queues it for the
//!   master (the slave posts it in EoE fragments when the master reads its mailbox);
//! - the writer writes each frame the master sent through EoE into the TAP, and applies
//!   what Set IP parameter gave the slave: its MAC and IPv4 address (with the mask, when
//!   the request had one) become the TAP's, so the address the master sets is the one the
//!   device answers on. The gateway, DNS server and name are only stored (Get IP answers
//!   them): they belong to the namespace's routing and resolver, which the bridge leaves
//!   to whoever set the namespace up.
//!
//! The TAP carries bare Ethernet frames (`IFF_NO_PI`), is not persistent and is made with
//! its link up; it goes away when ecat-sim exits. Everything is an `ioctl` (as `ip`
//! does it), no process is started.

use std::io;
use std::net::Ipv4Addr;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use sim::device::eoe::{HostEvent, HostPort, IpConfig};

/// How long either thread waits before it looks at the stop flag again.
const TICK: Duration = Duration::from_millis(100);

/// Larger than any frame of a TAP at the default MTU (1500 + Ethernet header); a longer
/// frame (a larger MTU set by hand) is cut here, and TCP finds its way around it.
const FRAME_BUF: usize = 2048;

/// The running bridge; [`TapBridge::stop`] ends its threads (the TAP goes with them).
#[derive(Debug)]
pub struct TapBridge {
    threads: Vec<JoinHandle<()>>,
}

impl TapBridge {
    /// Creates the TAP `name`, attaches `port` to it and starts the two threads; they run
    /// until `stop` is set.
    pub fn start(name: &str, port: &HostPort, stop: &Arc<AtomicBool>) -> io::Result<TapBridge> {
        let tap = Arc::new(open_tap(name)?);
        let up = ifreq_ioctl(name, libc::SIOCGIFFLAGS, |_| {})?;
        ifreq_ioctl(name, libc::SIOCSIFFLAGS, |r| {
            // SAFETY: SIOCGIFFLAGS filled the flags member of `up`.
            r.ifr_ifru.ifru_flags =
                unsafe { up.ifr_ifru.ifru_flags } | libc::IFF_UP as libc::c_short;
        })?;
        port.attach();
        let reader = {
            let (tap, port, stop) = (Arc::clone(&tap), port.clone(), Arc::clone(stop));
            std::thread::Builder::new()
                .name("eoe-tap-read".into())
                .spawn(move || read_frames(&tap, &port, &stop))?
        };
        let writer = {
            let (port, stop, name) = (port.clone(), Arc::clone(stop), name.to_owned());
            std::thread::Builder::new()
                .name("eoe-tap-write".into())
                .spawn(move || write_frames(&tap, &name, &port, &stop))?
        };
        Ok(TapBridge {
            threads: vec![reader, writer],
        })
    }

    /// Waits for both threads, which end within [`TICK`] of the stop flag.
    pub fn stop(self) {
        for thread in self.threads {
            let _ = thread.join();
        }
    }
}

fn read_frames(tap: &OwnedFd, port: &HostPort, stop: &AtomicBool) {
    let mut buf = [0u8; FRAME_BUF];
    let timeout = libc::c_int::try_from(TICK.as_millis()).unwrap_or(100);
    while !stop.load(Ordering::Relaxed) {
        let mut poll = libc::pollfd {
            fd: tap.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd.
        if unsafe { libc::poll(&mut poll, 1, timeout) } <= 0 {
            continue;
        }
        // SAFETY: reading at most `buf.len()` bytes into `buf`.
        let n = unsafe { libc::read(tap.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
        if let Ok(len) = usize::try_from(n)
            && len > 0
        {
            // A full queue drops the frame and counts it (`HostPort::drops`).
            port.send_to_master(buf[..len].to_vec());
        }
    }
}

fn write_frames(tap: &OwnedFd, name: &str, port: &HostPort, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        match port.next_event(TICK) {
            Some(HostEvent::Frame(frame)) => {
                // A frame the kernel refuses (the link set down by hand) is lost, as on a
                // wire; the next one may pass.
                // SAFETY: writing `frame.len()` bytes from `frame`.
                let _ = unsafe { libc::write(tap.as_raw_fd(), frame.as_ptr().cast(), frame.len()) };
            }
            Some(HostEvent::IpConfig(config)) => match apply(name, &config) {
                Ok(()) => eprintln!("ecat-sim: {name}: {}", describe(&config)),
                Err(err) => eprintln!("ecat-sim: {name}: cannot apply Set IP: {err}"),
            },
            None => {}
        }
    }
}

/// What Set IP gave the slave, as the TAP now has it.
fn describe(config: &IpConfig) -> String {
    let mac = config.mac.map_or_else(
        || "unchanged".to_owned(),
        |m| {
            let hex: Vec<String> = m.iter().map(|b| format!("{b:02x}")).collect();
            hex.join(":")
        },
    );
    let ip = config
        .ip
        .map_or_else(|| "unchanged".to_owned(), |ip| ip.to_string());
    format!("Set IP applied: mac {mac}, address {ip}")
}

/// Applies the slave's MAC and IPv4 address (and mask) to the TAP.
fn apply(name: &str, config: &IpConfig) -> io::Result<()> {
    if let Some(mac) = config.mac {
        ifreq_ioctl(name, libc::SIOCSIFHWADDR, |r| {
            // SAFETY: writing plain data into the union's `sockaddr` member.
            let hw = unsafe { &mut r.ifr_ifru.ifru_hwaddr };
            hw.sa_family = libc::ARPHRD_ETHER;
            for (slot, byte) in hw.sa_data.iter_mut().zip(mac) {
                *slot = byte as libc::c_char;
            }
        })?;
    }
    if let Some(ip) = config.ip {
        ifreq_ioctl(name, libc::SIOCSIFADDR, |r| r.ifr_ifru.ifru_addr = inet(ip))?;
        if let Some(mask) = config.subnet_mask {
            ifreq_ioctl(name, libc::SIOCSIFNETMASK, |r| {
                r.ifr_ifru.ifru_netmask = inet(mask);
            })?;
        }
    }
    Ok(())
}

/// `/dev/net/tun` attached to a new TAP interface `name` (Ethernet frames, no packet
/// information header).
fn open_tap(name: &str) -> io::Result<OwnedFd> {
    // SAFETY: a NUL-terminated path and plain flags; the result is checked.
    let raw = unsafe { libc::open(c"/dev/net/tun".as_ptr(), libc::O_RDWR | libc::O_CLOEXEC) };
    if raw < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: a descriptor just opened, owned by nobody else.
    let tun = unsafe { OwnedFd::from_raw_fd(raw) };
    let mut request = named_ifreq(name)?;
    request.ifr_ifru.ifru_flags = (libc::IFF_TAP | libc::IFF_NO_PI) as libc::c_short;
    // SAFETY: TUNSETIFF reads and writes one `ifreq`.
    if unsafe { libc::ioctl(tun.as_raw_fd(), libc::TUNSETIFF, &mut request) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(tun)
}

/// Runs the interface ioctl `request` on `name` with an `ifreq` that `fill` completed, on
/// a datagram socket of its own; returns the `ifreq` as the kernel left it.
fn ifreq_ioctl(
    name: &str,
    request: libc::c_ulong,
    fill: impl FnOnce(&mut libc::ifreq),
) -> io::Result<libc::ifreq> {
    let mut ifr = named_ifreq(name)?;
    fill(&mut ifr);
    // SAFETY: plain arguments; the result is checked.
    let raw = unsafe { libc::socket(libc::AF_INET, libc::SOCK_DGRAM | libc::SOCK_CLOEXEC, 0) };
    if raw < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: a descriptor just opened, owned by nobody else (closed on return).
    let socket = unsafe { OwnedFd::from_raw_fd(raw) };
    // SAFETY: every request used here reads or writes one `ifreq`.
    if unsafe { libc::ioctl(socket.as_raw_fd(), request, &mut ifr) } < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(ifr)
}

fn named_ifreq(name: &str) -> io::Result<libc::ifreq> {
    if name.is_empty() || name.len() >= libc::IFNAMSIZ || name.contains(['/', '\0', ' ']) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("bad interface name {name:?}"),
        ));
    }
    // SAFETY: `ifreq` is plain data; all zeroes is a valid value.
    let mut ifr: libc::ifreq = unsafe { std::mem::zeroed() };
    for (slot, byte) in ifr.ifr_name.iter_mut().zip(name.bytes()) {
        *slot = byte as libc::c_char;
    }
    Ok(ifr)
}

/// An IPv4 address as the `sockaddr` the interface ioctls take.
fn inet(address: Ipv4Addr) -> libc::sockaddr {
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
    fn names_the_kernel_would_refuse_are_refused_before_any_call() {
        for bad in ["", "a/b", "has space", "sixteen-chars-xx"] {
            let err = named_ifreq(bad).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{bad:?}");
        }
        assert!(named_ifreq("eoe-dev0").is_ok());
    }

    #[test]
    fn an_address_is_laid_out_as_sockaddr_in() {
        let sa = inet(Ipv4Addr::new(10, 78, 0, 2));
        assert_eq!(sa.sa_family, libc::AF_INET as libc::sa_family_t);
        let bytes: Vec<u8> = sa.sa_data[..6].iter().map(|&b| b as u8).collect();
        assert_eq!(bytes, [0, 0, 10, 78, 0, 2]);
    }
}
