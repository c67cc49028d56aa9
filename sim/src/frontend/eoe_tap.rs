//! `--eoe-tap NAME`: an EoE slave's Ethernet side bridged to a TAP interface in ecat-sim's
//! own network namespace, so the Linux stack there is the device behind the slave (and
//! `iperf3 -s` or any server can run behind it).
//!
//! Two threads beside the frame loop, which they meet only through the slave's
//! [`HostPort`] (bounded queues, drops counted):
//! - the reader takes each frame the kernel sends out of the TAP and queues it for the
//!   master (the slave posts it in EoE fragments when the master reads its mailbox); while
//!   that queue is full it waits, as a network card with a full transmit ring stops its
//!   queue, so the frames stay in the kernel and the device's TCP slows down instead of
//!   losing them (a frame dropped here cost a retransmission each: 9 % of them at 1 KiB
//!   mailboxes, docs/performance.md "EoE");
//! - the writer writes each frame the master sent through EoE into the TAP, and applies
//!   what Set IP parameter gave the slave: its MAC and IPv4 address (with the mask, when
//!   the request had one) become the TAP's, so the address the master sets is the one the
//!   device answers on. The gateway, DNS server and name are only stored (Get IP answers
//!   them): they belong to the namespace's routing and resolver, which the bridge leaves
//!   to whoever set the namespace up.
//!
//! The TAP carries bare Ethernet frames (`IFF_NO_PI`), is not persistent and is made with
//! its link up; it goes away when ecat-sim exits. Everything is an `ioctl` through
//! master-core's network-device controls (`ecat_link::netdev`, which ecatd's own EoE
//! interfaces use too), no process is started.

use std::io;
use std::os::fd::{AsRawFd, OwnedFd};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use ecat_link::netdev;
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
        let tap = Arc::new(netdev::open_tap(name, false)?);
        netdev::set_link_up(name, true)?;
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
            let mut frame = buf[..len].to_vec();
            while let Err(back) = port.send_to_master_waiting(frame, TICK) {
                if stop.load(Ordering::Relaxed) {
                    return;
                }
                frame = back;
            }
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
        netdev::set_mac(name, mac)?;
    }
    if let Some(ip) = config.ip {
        netdev::set_ipv4(name, ip, config.subnet_mask)?;
    }
    Ok(())
}
