//! How many frames per second the simulator sustains, in-process (`Segment::process`), for
//! 1, 16 and 256 slaves (`Topology::repeated`).
//!
//! The segment is brought to OP the way a master does it (station addresses, SyncManagers
//! from each slave's SII, FMMUs packed into one logical image, PREOP → SAFEOP → OP), then
//! timed on the frames a master sends most:
//! - cyclic: one LRW over every slave's process data plus a BRD of the AL status;
//! - mailbox: an FPRD of the first mailbox slave's SM1 (the mailbox poll).
//!
//! Run: `cargo bench -p sim --bench throughput`. Each frame starts as a fresh copy of its
//! template (as a received frame would), so working counters do not pile up.

use std::hint::black_box;
use std::time::{Duration, Instant};

use master_core::link::MAX_FRAME_LEN;
use master_core::wire::command::{Command, DatagramAddress};
use master_core::wire::datagram::{DatagramRepr, FrameBuilder};
use master_core::wire::frame::EthercatFrame;
use master_core::wire::register::fmmu::{FMMU_LEN, Fmmu, FmmuRepr};
use master_core::wire::register::sync_manager::{SM_LEN, SyncManager, SyncManagerRepr};
use master_core::wire::sii::SiiImage;
use master_core::wire::sii::syncm::SyncmType;
use sim::segment::Segment;
use sim::topology::{Topology, build};

const MASTER_MAC: [u8; 6] = [0x02, 0, 0, 0, 0, 0x01];
/// How long each measurement runs.
const MEASURE: Duration = Duration::from_millis(700);

fn station(position: usize) -> u16 {
    0x1001 + position as u16
}

/// One frame of `datagrams`.
fn frame(datagrams: &[DatagramRepr<'_>]) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let mut builder = FrameBuilder::new(&mut buf).unwrap();
    for d in datagrams {
        builder.push(d).unwrap();
    }
    let len = builder.finish(MASTER_MAC).unwrap();
    buf.truncate(len);
    buf
}

/// Sends one datagram; returns its data and working counter.
fn one(
    segment: &mut Segment,
    command: Command,
    address: DatagramAddress,
    data: &[u8],
) -> (Vec<u8>, u16) {
    let mut f = frame(&[DatagramRepr::request(command, 0, address, data)]);
    assert!(segment.process(&mut f), "frame returned");
    let parsed = EthercatFrame::parse(&f).unwrap();
    let d = parsed.datagrams().unwrap().next().unwrap().unwrap();
    (d.data.to_vec(), d.wkc)
}

fn fpwr(segment: &mut Segment, position: usize, ado: u16, data: &[u8]) {
    let address = DatagramAddress::Node {
        station: station(position),
        ado,
    };
    let (_, wkc) = one(segment, Command::Fpwr, address, data);
    assert_eq!(wkc, 1, "FPWR 0x{ado:04X} to slave {position}");
}

/// What the bring-up leaves for the timed frames.
struct Image {
    /// Bytes of the logical process image (outputs, then inputs).
    len: u32,
    /// The first mailbox slave: position, SM1 start and length.
    mailbox_slave: Option<(usize, u16, u16)>,
}

/// Brings every slave to OP with its process data mapped into one logical image.
fn bring_up(segment: &mut Segment) -> Image {
    let count = segment.len();
    let mut out_log = 0u32;
    let mut mailbox_slave = None;
    // First pass: addresses, SyncManagers, PREOP; collect the process-data SMs.
    let mut pd: Vec<(usize, SyncmType, u16, u16)> = Vec::new();
    for p in 0..count {
        one(
            segment,
            Command::Apwr,
            DatagramAddress::position(p as u16, 0x0010),
            &station(p).to_le_bytes(),
        );
        let sii = segment.esc(p).unwrap().sii().to_vec();
        let image = SiiImage::parse(&sii).unwrap();
        for (i, sm) in image.syncm.iter().enumerate() {
            let repr = match sm.sm_type {
                SyncmType::MailboxOut => SyncManagerRepr::mailbox_out(sm.start, sm.length),
                SyncmType::MailboxIn => {
                    mailbox_slave.get_or_insert((p, sm.start, sm.length));
                    SyncManagerRepr::mailbox_in(sm.start, sm.length)
                }
                SyncmType::Outputs if sm.length > 0 => {
                    pd.push((p, SyncmType::Outputs, sm.start, sm.length));
                    SyncManagerRepr::outputs(sm.start, sm.length)
                }
                SyncmType::Inputs if sm.length > 0 => {
                    pd.push((p, SyncmType::Inputs, sm.start, sm.length));
                    SyncManagerRepr::inputs(sm.start, sm.length)
                }
                _ => continue,
            };
            let mut bytes = [0u8; SM_LEN];
            repr.emit(&mut SyncManager::new_unchecked(&mut bytes[..]))
                .unwrap();
            fpwr(segment, p, 0x0800 + (i * SM_LEN) as u16, &bytes);
        }
        fpwr(segment, p, 0x0120, &2u16.to_le_bytes());
    }
    // Outputs first in the logical image, inputs behind them; one FMMU per direction.
    let out_total: u32 = pd
        .iter()
        .filter(|(_, t, _, _)| *t == SyncmType::Outputs)
        .map(|(_, _, _, len)| u32::from(*len))
        .sum();
    let mut in_log = out_total;
    for &(p, kind, start, length) in &pd {
        let (repr, slot) = if kind == SyncmType::Outputs {
            let r = FmmuRepr::outputs(out_log, length, start);
            out_log += u32::from(length);
            (r, 0)
        } else {
            let r = FmmuRepr::inputs(in_log, length, start);
            in_log += u32::from(length);
            (r, 1)
        };
        let mut bytes = [0u8; FMMU_LEN];
        repr.emit(&mut Fmmu::new_unchecked(&mut bytes[..])).unwrap();
        fpwr(segment, p, 0x0600 + (slot * FMMU_LEN) as u16, &bytes);
    }
    for p in 0..count {
        fpwr(segment, p, 0x0120, &4u16.to_le_bytes());
    }
    // Slaves leave SAFEOP for OP only with valid outputs (AL status 0x0019 otherwise).
    let zeros = vec![0u8; in_log as usize];
    one(segment, Command::Lrw, DatagramAddress::Logical(0), &zeros);
    for p in 0..count {
        fpwr(segment, p, 0x0120, &8u16.to_le_bytes());
    }
    let (status, wkc) = one(
        segment,
        Command::Brd,
        DatagramAddress::broadcast(0x0130),
        &[0, 0],
    );
    assert_eq!(usize::from(wkc), count);
    let codes: Vec<u16> = (0..count)
        .map(|p| segment.esc(p).unwrap().read_u16(0x0134))
        .collect();
    assert_eq!(
        status[0] & 0x1F,
        0x08,
        "every slave in OP, no error: {codes:04X?}"
    );
    Image {
        len: in_log,
        mailbox_slave,
    }
}

/// Frames per second `segment` processes `template` at, and the working counter of the
/// template's first datagram.
fn measure(segment: &mut Segment, template: &[u8]) -> (f64, u16) {
    let mut work = template.to_vec();
    assert!(segment.process(&mut work));
    let parsed = EthercatFrame::parse(&work).unwrap();
    let wkc = parsed.datagrams().unwrap().next().unwrap().unwrap().wkc;
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
        let image = bring_up(&mut segment);
        let zeros = vec![0u8; image.len as usize];
        let cyclic = frame(&[
            DatagramRepr::request(Command::Lrw, 0, DatagramAddress::Logical(0), &zeros),
            DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0x0130), &[0, 0]),
        ]);
        let (cyclic_rate, wkc) = measure(&mut segment, &cyclic);
        let mailbox_rate = match image.mailbox_slave {
            Some((p, start, length)) => {
                let data = vec![0u8; usize::from(length)];
                let address = DatagramAddress::Node {
                    station: station(p),
                    ado: start,
                };
                let poll = frame(&[DatagramRepr::request(Command::Fprd, 0, address, &data)]);
                format!("{:.0}", measure(&mut segment, &poll).0)
            }
            None => "-".to_owned(),
        };
        println!(
            "| {count} | {} | {cyclic_rate:.0} | {wkc} | {:.0} | {mailbox_rate} |",
            image.len,
            1e9 / cyclic_rate / count as f64
        );
    }
}
