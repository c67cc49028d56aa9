//! The frame loop of a ring (`--backup-iface`): the segment between the master's two
//! ports (cable redundancy, ETG.1000.3 §4.2).
//!
//! A frame taken from either interface enters the segment from that master port
//! ([`Segment::process_from`]) and is sent out on the interface of the port it comes back
//! on: in a closed ring the other one, after a break the same one. The loop waits on both
//! sockets at once (`poll(2)`), and like the one-port loop ([`super::serve`]) it wakes at
//! least every [`IDLE`] on a silent wire for the watchdogs, the stop flag and the rate
//! line. One thread, one buffer, no allocation per frame.

use std::io::{self, ErrorKind, Write};
use std::os::fd::RawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ecat_link::{Link, MAX_FRAME_LEN, Wait};
use sim::esc::ManualTime;
use sim::segment::{Port, Segment};

use super::changes::Changes;
use super::counter::FrameCounter;
use super::serve::IDLE;

/// Waits on the two sockets: `wait(timeout, [primary, backup])` returns once one of the
/// watched ones may have a frame (`true`) or `timeout` passed (`false`).
pub trait WaitEither {
    /// Waits as described on the trait.
    fn wait(&mut self, timeout: Duration, watch: [bool; 2]) -> io::Result<bool>;
}

/// [`WaitEither`] on two file descriptors with `poll(2)`.
#[derive(Debug, Clone, Copy)]
pub struct PollFds {
    fds: [RawFd; 2],
}

impl PollFds {
    /// Polls `primary` and `backup`, the sockets under the two links; they must stay open
    /// while this is used (a closed descriptor would only make `poll` report it invalid).
    pub fn new(primary: RawFd, backup: RawFd) -> Self {
        PollFds {
            fds: [primary, backup],
        }
    }
}

impl WaitEither for PollFds {
    fn wait(&mut self, timeout: Duration, watch: [bool; 2]) -> io::Result<bool> {
        // poll(2) skips negative descriptors: an unwatched port is not looked at.
        let mut fds = [0, 1].map(|i| libc::pollfd {
            fd: if watch[i] { self.fds[i] } else { -1 },
            events: libc::POLLIN,
            revents: 0,
        });
        let millis = libc::c_int::try_from(timeout.as_millis()).unwrap_or(libc::c_int::MAX);
        // SAFETY: `fds` is an array of two valid pollfd structures, and 2 is its length.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), 2, millis) };
        if ready < 0 {
            let err = io::Error::last_os_error();
            // A signal (SIGTERM) interrupts the wait: the loop looks at its stop flag.
            return if err.kind() == ErrorKind::Interrupted {
                Ok(false)
            } else {
                Err(err)
            };
        }
        Ok(ready > 0)
    }
}

/// Answers frames on `primary` and `backup` (the master's two ports) with `segment` until
/// `stop` is set; returns the final counts.
///
/// As [`super::serve::serve`]: `time` follows the time since the loop started, `changes`
/// are made before the next frame, a frame the kernel cannot queue for sending is counted
/// and lost, an interface that is down is waited out (the other port goes on being
/// served), and any other link error ends the loop.
#[allow(clippy::too_many_arguments)] // the one-port loop's arguments and a second port
pub fn serve_ring(
    primary: &mut impl Link,
    backup: &mut impl Link,
    waiter: &mut impl WaitEither,
    segment: &mut Segment,
    time: &ManualTime,
    stop: &AtomicBool,
    changes: &Changes,
    report: &mut impl Write,
) -> io::Result<FrameCounter> {
    let origin = Instant::now();
    let mut counter = FrameCounter::new(origin);
    let mut buf = [0u8; MAX_FRAME_LEN];
    let elapsed = || u64::try_from(origin.elapsed().as_nanos()).unwrap_or(u64::MAX);
    while !stop.load(Ordering::Relaxed) {
        if let Some(rate) = counter.due(Instant::now()) {
            // A closed stderr must not stop the simulator.
            let _ = counter.write_line(rate, report);
        }
        let mut heard = false;
        let mut up = [true; 2];
        for (i, port) in [Port::Primary, Port::Backup].into_iter().enumerate() {
            let received = match port {
                Port::Primary => primary.recv(&mut buf, Wait::NoWait),
                Port::Backup => backup.recv(&mut buf, Wait::NoWait),
            };
            let len = match received {
                Ok(Some(len)) => len,
                Ok(None) => continue,
                // The interface went down (a cut cable): not watched until it answers again.
                Err(err) if err.kind() == ErrorKind::NetworkDown => {
                    up[i] = false;
                    continue;
                }
                Err(err) => return Err(err),
            };
            heard = true;
            counter.frames_in += 1;
            changes.apply(segment, report);
            time.set(elapsed());
            let frame = &mut buf[..len];
            let Some(out) = segment.process_from(port, frame) else {
                counter.not_returned += 1;
                continue;
            };
            let sent = match out {
                Port::Primary => primary.send(frame),
                Port::Backup => backup.send(frame),
            };
            match sent {
                Ok(()) => counter.frames_out += 1,
                // No room in the kernel's queue, or the interface is down: lost, as on a wire.
                Err(err)
                    if matches!(err.kind(), ErrorKind::WouldBlock | ErrorKind::NetworkDown) =>
                {
                    counter.send_dropped += 1
                }
                Err(err) => return Err(err),
            }
        }
        if heard {
            continue;
        }
        let woken = if up == [false, false] {
            // Both interfaces down: polled, not spun on.
            std::thread::sleep(IDLE);
            false
        } else {
            waiter.wait(IDLE, up)?
        };
        if !woken {
            time.set(elapsed());
            segment.idle();
        }
    }
    Ok(counter)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frontend::test_frames::brd_frame;
    use ecat_link::MemoryLink;
    use ecat_wire::frame::EthercatFrame;
    use sim::topology::{Topology, build_with_handles};

    use super::super::changes::Change;

    /// Never sleeps: the memory links have no descriptor to poll, so the loop spins while
    /// the test runs (a few frames).
    struct Spin;

    impl WaitEither for Spin {
        fn wait(&mut self, _timeout: Duration, _watch: [bool; 2]) -> io::Result<bool> {
            std::thread::yield_now();
            Ok(true)
        }
    }

    /// Sends a BRD on the master's port `from` and returns its working counter as it comes
    /// back on port `to`.
    fn round_trip(master: &mut [MemoryLink; 2], from: Port, to: Port) -> u16 {
        let index = |port| usize::from(port == Port::Backup);
        master[index(from)].send(&brd_frame()).unwrap();
        let mut rx = [0u8; MAX_FRAME_LEN];
        let deadline = Instant::now() + Duration::from_secs(10);
        let n = master[index(to)]
            .recv(&mut rx, Wait::Until(deadline))
            .unwrap()
            .expect("frame answered on the expected port");
        let frame = EthercatFrame::parse(&rx[..n]).unwrap();
        let datagram = frame.datagrams().unwrap().next().unwrap().unwrap();
        datagram.wkc
    }

    #[test]
    fn frames_come_back_on_the_port_the_ring_sends_them_to() {
        let topology = Topology::default_segment();
        let n = topology.slaves.len() as u16;
        let built = build_with_handles(&topology).unwrap();
        let mut segment = built.segment;
        segment.set_ring(true);
        let (master_primary, mut wire_primary) = MemoryLink::pair(8);
        let (master_backup, mut wire_backup) = MemoryLink::pair(8);
        let stop = AtomicBool::new(false);
        let changes = Changes::default();
        let counter = std::thread::scope(|scope| {
            let server = scope.spawn(|| {
                serve_ring(
                    &mut wire_primary,
                    &mut wire_backup,
                    &mut Spin,
                    &mut segment,
                    &built.time,
                    &stop,
                    &changes,
                    &mut io::sink(),
                )
                .unwrap()
            });
            let master = &mut [master_primary, master_backup];
            let (primary, backup) = (Port::Primary, Port::Backup);
            assert_eq!(round_trip(master, primary, backup), n);
            assert_eq!(round_trip(master, backup, primary), 0);
            changes.request(Change::Break(2));
            assert_eq!(round_trip(master, primary, primary), 2);
            assert_eq!(round_trip(master, backup, backup), n - 2);
            changes.request(Change::Heal);
            assert_eq!(round_trip(master, primary, backup), n);
            stop.store(true, Ordering::Relaxed);
            server.join().unwrap()
        });
        assert_eq!((counter.frames_in, counter.frames_out), (5, 5));
    }
}
