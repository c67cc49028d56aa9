//! The frame loop: receive a frame, run it through the segment, send it back.
//!
//! One thread, one buffer, no allocation per frame. The loop wakes at least every
//! [`IDLE`] on a silent wire: to let the slaves' watchdogs run out on time, as an ESC's
//! hardware does without frames (a slave in OP whose master went quiet switches its outputs
//! off), to look at the stop flag and to print the rate line.

use std::io::{self, ErrorKind, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ecat_link::{Link, MAX_FRAME_LEN, Wait};
use sim::esc::ManualTime;
use sim::segment::Segment;

use super::changes::Changes;
use super::counter::FrameCounter;

/// Longest wait for a frame before the loop lets time pass in the segment and looks at its
/// stop flag again: a watchdog runs out at most this late (10 % of the default 100 ms).
pub const IDLE: Duration = Duration::from_millis(10);

/// Answers frames on `link` with `segment` until `stop` is set; returns the final counts.
///
/// `time` is the segment's time base: it is set to the time since the loop started before
/// each frame, so the slaves' distributed clocks run in real time. Rate lines go to `report`
/// about once per second. A frame the kernel cannot queue for sending is counted and lost
/// (as on a wire); an interface that goes down (a cut cable) is waited out; any other link
/// error ends the loop. `changes` are made before the next frame.
pub fn serve(
    link: &mut impl Link,
    segment: &mut Segment,
    time: &ManualTime,
    stop: &AtomicBool,
    changes: &Changes,
    report: &mut impl Write,
) -> io::Result<FrameCounter> {
    let origin = Instant::now();
    let mut counter = FrameCounter::new(origin);
    let mut buf = [0u8; MAX_FRAME_LEN];
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        if let Some(rate) = counter.due(now) {
            // A closed stderr must not stop the simulator.
            let _ = counter.write_line(rate, report);
        }
        let elapsed = || u64::try_from(origin.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let received = match link.recv(&mut buf, Wait::Until(now + IDLE)) {
            Ok(received) => received,
            // The interface went down (a cut cable): the slaves keep their AL state, apart
            // from their watchdogs, and answer again once it is back up. Polled, not spun on.
            Err(err) if err.kind() == ErrorKind::NetworkDown => {
                std::thread::sleep(IDLE);
                None
            }
            Err(err) => return Err(err),
        };
        let Some(len) = received else {
            time.set(elapsed());
            segment.idle();
            continue;
        };
        counter.frames_in += 1;
        changes.apply(segment, report);
        time.set(elapsed());
        let frame = &mut buf[..len];
        if !segment.process(frame) {
            counter.not_returned += 1;
            continue;
        }
        match link.send(frame) {
            Ok(()) => counter.frames_out += 1,
            // No room in the kernel's queue, or the interface is down: lost, as on a wire.
            Err(err) if matches!(err.kind(), ErrorKind::WouldBlock | ErrorKind::NetworkDown) => {
                counter.send_dropped += 1
            }
            Err(err) => return Err(err),
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

    #[test]
    fn answers_frames_until_stopped_and_counts_them() {
        let topology = Topology::default_segment();
        let built = build_with_handles(&topology).unwrap();
        let (mut master, mut wire) = MemoryLink::pair(8);
        let stop = AtomicBool::new(false);
        let mut segment = built.segment;
        let counter = std::thread::scope(|scope| {
            let server = scope.spawn(|| {
                serve(
                    &mut wire,
                    &mut segment,
                    &built.time,
                    &stop,
                    &Changes::default(),
                    &mut io::sink(),
                )
                .unwrap()
            });
            for _ in 0..3 {
                master.send(&brd_frame()).unwrap();
                let mut rx = [0u8; MAX_FRAME_LEN];
                let deadline = Instant::now() + Duration::from_secs(10);
                let n = master
                    .recv(&mut rx, Wait::Until(deadline))
                    .unwrap()
                    .expect("frame answered");
                let frame = EthercatFrame::parse(&rx[..n]).unwrap();
                let datagram = frame.datagrams().unwrap().next().unwrap().unwrap();
                assert_eq!(usize::from(datagram.wkc), topology.slaves.len());
            }
            // Not EtherCAT: an IPv4 EtherType; the segment does not return it.
            let mut other = brd_frame();
            other[12..14].copy_from_slice(&[0x08, 0x00]);
            master.send(&other).unwrap();
            stop.store(true, Ordering::Relaxed);
            server.join().unwrap()
        });
        assert_eq!(counter.frames_out, 3);
        assert!(counter.frames_in >= 3);
    }
}
