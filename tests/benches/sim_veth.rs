//! Frames per second through `ecat-sim` over a veth pair, one frame in flight (ping-pong):
//! a raw socket in one network namespace, `ecat-sim --slaves N` in the other. The segment
//! is first brought to OP over the wire (the same bring-up and frames as the in-process
//! bench `sim/benches/throughput.rs`, whose support file is included here), so the numbers
//! compare: the difference is the cost of the link (syscalls, wake-ups, veth).
//!
//! Needs root. Run: `cargo bench -p ecat-tests --bench sim_veth`.

#[allow(dead_code)]
#[path = "../../sim/benches/support/bring_up.rs"]
mod bring_up;

use std::time::{Duration, Instant};

use bring_up::{Exchange, bring_up, cyclic_frame, first_wkc, mailbox_frame};
use ecat_tests::rig::{MASTER_IFACE, Rig, SIM_IFACE};
use ecat_tests::sim_process::SimProcess;
use master_core::link::{Link, MAX_FRAME_LEN, RawSocket, RawSocketOptions, Wait};
use sim::topology::{Topology, build};

/// How long each measurement runs.
const MEASURE: Duration = Duration::from_millis(700);
/// How long to wait for one frame to come back; a lost frame fails the bench.
const PATIENCE: Duration = Duration::from_secs(2);

struct Wire {
    socket: RawSocket,
    rx: Vec<u8>,
}

impl Exchange for Wire {
    fn exchange(&mut self, frame: &mut [u8]) -> bool {
        self.socket.send(frame).expect("send");
        let deadline = Instant::now() + PATIENCE;
        match self.socket.recv(&mut self.rx, Wait::Until(deadline)) {
            Ok(Some(len)) if len == frame.len() => {
                frame.copy_from_slice(&self.rx[..len]);
                true
            }
            _ => false,
        }
    }
}

/// Round trips per second of `template`, and its first working counter.
fn measure(wire: &mut Wire, template: &[u8]) -> (f64, u16) {
    let mut work = template.to_vec();
    assert!(wire.exchange(&mut work), "frame returned");
    let wkc = first_wkc(&work);
    let start = Instant::now();
    let mut frames = 0u64;
    while start.elapsed() < MEASURE {
        work.copy_from_slice(template);
        assert!(wire.exchange(&mut work), "frame returned");
        frames += 1;
    }
    (frames as f64 / start.elapsed().as_secs_f64(), wkc)
}

fn row(count: usize, busy_poll: bool) {
    let topology = Topology::repeated(count);
    let local = build(&topology).unwrap();
    let siis: Vec<Vec<u8>> = (0..count)
        .map(|p| local.esc(p).unwrap().sii().to_vec())
        .collect();
    let rig = Rig::new();
    let n = count.to_string();
    let mut args = vec!["--slaves", n.as_str()];
    if busy_poll {
        args.push("--busy-poll");
    }
    let mut sim = SimProcess::start(&rig.sim, SIM_IFACE, &args);
    let (cyclic, wkc, mailbox, image_len) = rig.master.run_inside(|| {
        let options = RawSocketOptions {
            busy_poll,
            ..RawSocketOptions::default()
        };
        let socket = RawSocket::open(MASTER_IFACE, options).expect("raw socket");
        let mut wire = Wire {
            socket,
            rx: vec![0u8; MAX_FRAME_LEN],
        };
        let image = bring_up(&mut wire, &siis);
        let (cyclic, wkc) = measure(&mut wire, &cyclic_frame(&image));
        let mailbox = mailbox_frame(&image).map(|poll| measure(&mut wire, &poll).0);
        (cyclic, wkc, mailbox, image.len)
    });
    sim.stop();
    let mailbox = mailbox.map_or("-".to_owned(), |r| format!("{r:.0}"));
    println!(
        "| {count} | {} | {image_len} | {cyclic:.0} | {wkc} | {:.1} | {mailbox} |",
        if busy_poll { "busy-poll" } else { "poll" },
        1e6 / cyclic
    );
}

fn main() {
    println!("ecat-sim over veth, one frame in flight, {MEASURE:?} per cell");
    println!(
        "| slaves | wait | image bytes | cyclic LRW+BRD frames/s | LRW wkc | µs/round trip | mailbox FPRD frames/s |"
    );
    println!("|---:|---|---:|---:|---:|---:|---:|");
    // Busy polling (`--busy-poll`) spins one core on each side; on a 2-core machine the
    // two spinners starve each other, so it is left out here (pass `busy` to try it).
    let busy = std::env::args().any(|a| a == "busy");
    for count in [1usize, 16, 256] {
        row(count, busy);
    }
}
