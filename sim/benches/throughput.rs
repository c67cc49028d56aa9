//! How many frames per second the simulator sustains, in-process (`Segment::process`), for
//! 1, 16 and 256 slaves (`Topology::repeated`).
//!
//! The segment is brought to OP the way a master does it (`support/bring_up.rs`), then timed
//! on the frames a master sends most:
//! - cyclic: one LRW over every slave's process data plus a BRD of the AL status;
//! - mailbox: an FPRD of the first mailbox slave's SM1 (the mailbox poll).
//!
//! Run: `cargo bench -p sim --bench throughput`. Each frame starts as a fresh copy of its
//! template (as a received frame would), so working counters do not pile up. The same
//! frames over veth through `ecat-sim`: `cargo bench -p ecat-tests --bench sim_veth`.

#[allow(dead_code)]
#[path = "support/bring_up.rs"]
mod bring_up;

use std::hint::black_box;
use std::time::{Duration, Instant};

use bring_up::{Exchange, bring_up, cyclic_frame, first_wkc, mailbox_frame};
use sim::segment::Segment;
use sim::topology::{Topology, build};

/// How long each measurement runs.
const MEASURE: Duration = Duration::from_millis(700);

impl Exchange for Segment {
    fn exchange(&mut self, frame: &mut [u8]) -> bool {
        self.process(frame)
    }
}

/// Frames per second `segment` processes `template` at, and the working counter of the
/// template's first datagram.
fn measure(segment: &mut Segment, template: &[u8]) -> (f64, u16) {
    let mut work = template.to_vec();
    assert!(segment.process(&mut work));
    let wkc = first_wkc(&work);
    let start = Instant::now();
    let mut frames = 0u64;
    while start.elapsed() < MEASURE {
        for _ in 0..64 {
            work.copy_from_slice(template);
            black_box(segment.process(black_box(&mut work)));
        }
        frames += 64;
    }
    (frames as f64 / start.elapsed().as_secs_f64(), wkc)
}

fn main() {
    println!("sim throughput, in-process (Segment::process), {MEASURE:?} per cell");
    println!(
        "| slaves | image bytes | cyclic LRW+BRD frames/s | LRW wkc | ns/slave/frame | mailbox FPRD frames/s |"
    );
    println!("|---:|---:|---:|---:|---:|---:|");
    for count in [1usize, 16, 256] {
        let mut segment = build(&Topology::repeated(count)).unwrap();
        let siis: Vec<Vec<u8>> = (0..count)
            .map(|p| segment.esc(p).unwrap().sii().to_vec())
            .collect();
        let image = bring_up(&mut segment, &siis);
        let (cyclic_rate, wkc) = measure(&mut segment, &cyclic_frame(&image));
        let mailbox_rate = match mailbox_frame(&image) {
            Some(poll) => format!("{:.0}", measure(&mut segment, &poll).0),
            None => "-".to_owned(),
        };
        println!(
            "| {count} | {} | {cyclic_rate:.0} | {wkc} | {:.0} | {mailbox_rate} |",
            image.len,
            1e9 / cyclic_rate / count as f64
        );
    }
}
