//! Bringing a segment to OP the way a master does, for the benchmarks: station addresses,
//! SyncManagers from each slave's SII, FMMUs packing every slave's process data into one
//! logical image (outputs, then inputs), PREOP → SAFEOP → (outputs once) → OP; and the
//! frames a master sends most. Shared by `sim/benches/throughput.rs` (in-process) and
//! `tests/benches/sim_veth.rs` (over veth), which include this file.

use ecat_link::MAX_FRAME_LEN;
use ecat_wire::command::{Command, DatagramAddress};
use ecat_wire::datagram::{DatagramRepr, FrameBuilder};
use ecat_wire::frame::EthercatFrame;
use ecat_wire::register::fmmu::{FMMU_LEN, Fmmu, FmmuRepr};
use ecat_wire::register::sync_manager::{SM_LEN, SyncManager, SyncManagerRepr};
use ecat_wire::sii::SiiImage;
use ecat_wire::sii::syncm::SyncmType;

const MASTER_MAC: [u8; 6] = [0x02, 0, 0, 0, 0, 0x01];

/// Something that runs a frame through a segment and puts the returned frame in its place.
pub trait Exchange {
    /// Returns false when no frame came back.
    fn exchange(&mut self, frame: &mut [u8]) -> bool;
}

pub fn station(position: usize) -> u16 {
    0x1001 + position as u16
}

/// One frame of `datagrams`.
pub fn frame(datagrams: &[DatagramRepr<'_>]) -> Vec<u8> {
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
    segment: &mut impl Exchange,
    command: Command,
    address: DatagramAddress,
    data: &[u8],
) -> (Vec<u8>, u16) {
    let mut f = frame(&[DatagramRepr::request(command, 0, address, data)]);
    assert!(segment.exchange(&mut f), "frame returned");
    let parsed = EthercatFrame::parse(&f).unwrap();
    let d = parsed.datagrams().unwrap().next().unwrap().unwrap();
    (d.data.to_vec(), d.wkc)
}

fn fpwr(segment: &mut impl Exchange, position: usize, ado: u16, data: &[u8]) {
    let address = DatagramAddress::Node {
        station: station(position),
        ado,
    };
    let (_, wkc) = one(segment, Command::Fpwr, address, data);
    assert_eq!(wkc, 1, "FPWR 0x{ado:04X} to slave {position}");
}

/// What the bring-up leaves for the timed frames.
pub struct Image {
    /// Bytes of the logical process image (outputs, then inputs).
    pub len: u32,
    /// The first mailbox slave: position, SM1 start and length.
    pub mailbox_slave: Option<(usize, u16, u16)>,
}

/// Brings every slave to OP with its process data mapped into one logical image; `siis`
/// are the slaves' SII images, by position.
pub fn bring_up(segment: &mut impl Exchange, siis: &[Vec<u8>]) -> Image {
    let count = siis.len();
    let mut out_log = 0u32;
    let mut mailbox_slave = None;
    // First pass: addresses, SyncManagers, PREOP; collect the process-data SMs.
    let mut pd: Vec<(usize, SyncmType, u16, u16)> = Vec::new();
    for (p, sii) in siis.iter().enumerate() {
        one(
            segment,
            Command::Apwr,
            DatagramAddress::position(p as u16, 0x0010),
            &station(p).to_le_bytes(),
        );
        let image = SiiImage::parse(sii).unwrap();
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
    // A slave in error shows it in its AL status code register (0x0134).
    assert_eq!(status[0] & 0x1F, 0x08, "every slave in OP, no error");
    Image {
        len: in_log,
        mailbox_slave,
    }
}

/// The cyclic frame: LRW over the whole image plus a BRD of the AL status.
pub fn cyclic_frame(image: &Image) -> Vec<u8> {
    let zeros = vec![0u8; image.len as usize];
    frame(&[
        DatagramRepr::request(Command::Lrw, 0, DatagramAddress::Logical(0), &zeros),
        DatagramRepr::request(Command::Brd, 1, DatagramAddress::broadcast(0x0130), &[0, 0]),
    ])
}

/// The mailbox poll: an FPRD of the first mailbox slave's SM1, if there is one.
pub fn mailbox_frame(image: &Image) -> Option<Vec<u8>> {
    let (p, start, length) = image.mailbox_slave?;
    let data = vec![0u8; usize::from(length)];
    let address = DatagramAddress::Node {
        station: station(p),
        ado: start,
    };
    Some(frame(&[DatagramRepr::request(
        Command::Fprd,
        0,
        address,
        &data,
    )]))
}

/// The working counter of the first datagram of a returned frame.
pub fn first_wkc(frame: &[u8]) -> u16 {
    let parsed = EthercatFrame::parse(frame).unwrap();
    parsed.datagrams().unwrap().next().unwrap().unwrap().wkc
}
