//! The two copies of a frame: one for the primary port, one for the backup port.
//!
//! Both carry every datagram of the bus's frame, so that a write reaches a slave on
//! either side of a break. Three things differ from the frame the bus built
//! (spec-notes §redundancy):
//! - **The probe.** Each copy ends with one more datagram, a BRD of the ESC type register
//!   (0x0000, one byte) whose index is the copy's sequence number: its working counter is
//!   the number of slaves that processed the copy, which is how the ring link knows how
//!   far each port reaches.
//! - **Position addressing on the backup copy.** The backup copy is processed, if at all,
//!   from the first slave behind the break onwards, so an auto-increment address counts
//!   from there: the ADP is shifted by that slave's position. With the ring closed (or not
//!   known) nobody processes the backup copy, except in the one frame that meets a cut: there
//!   position-addressed datagrams become NOPs so that they cannot reach the wrong slave.
//! - **The reference time (FRMW).** The side of a break without the reference clock would
//!   otherwise write the master's zeros into its clocks: there the datagram is addressed
//!   to that side's first clock instead (which then serves as its reference), or becomes a
//!   NOP if the side has no clock. Needs the clock plan ([`RingWatch::set_clocks`]).
//!
//! [`RingWatch::set_clocks`]: super::RingWatch::set_clocks

use crate::wire::command::{AddressingMode, Command};
use crate::wire::datagram::{Datagram, DatagramsMut, OVERHEAD};
use crate::wire::ethernet::{self, EthernetFrame};
use crate::wire::frame::EthercatFrame;

use super::status::{RingClock, RingState};

/// The probe: BRD 0x0000, one byte of data.
pub(crate) const PROBE_LEN: usize = OVERHEAD + 1;

/// Most datagrams one frame can hold (each takes at least its 12 bytes of overhead).
pub(crate) const MAX_DATAGRAMS: usize = ethernet::MAX_FRAME_LEN / OVERHEAD + 1;

/// The bit of the last source-MAC byte that marks the backup copy.
const BACKUP_MARK: u8 = 0x80;

/// The bit the first slave sets in the first source-MAC byte of a returning frame.
const RETURNED_BIT: u8 = 0x02;

/// Which copy a datagram's data is taken from when the two come back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) enum Prefer {
    /// Bit by bit from whichever copy changed it (spec-notes §redundancy).
    #[default]
    Changed,
    /// From the primary copy (the backup's datagram was re-addressed).
    Primary,
    /// From the backup copy (the primary's datagram was re-addressed).
    Backup,
}

/// What the ring looks like to the copies being built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Plan<'a> {
    pub state: RingState,
    /// Slaves the primary copy reaches.
    pub primary_side: u16,
    /// Position of the first slave the backup copy reaches.
    pub backup_first: u16,
    /// Distributed clocks by position (the first is the reference), or empty.
    pub clocks: &'a [RingClock],
}

/// The master port a copy is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Side {
    Primary,
    Backup,
}

/// Writes the copy of `frame` for `side` into `out`, with the probe numbered `seq`;
/// records into `prefer` which datagrams the copy re-addressed. Returns the copy's length,
/// or `None` if `frame` is not a well-formed, untagged EtherCAT datagram frame or the
/// probe does not fit (the caller then sends `frame` as it is).
pub(crate) fn build(
    frame: &[u8],
    side: Side,
    plan: &Plan<'_>,
    seq: u8,
    out: &mut [u8],
    prefer: &mut [Prefer; MAX_DATAGRAMS],
) -> Option<usize> {
    let parsed = EthercatFrame::parse(frame).ok()?;
    if parsed.payload_offset != ethernet::HEADER_LEN + crate::wire::frame::HEADER_LEN {
        return None;
    }
    let start = parsed.payload_offset;
    let end = start + parsed.payload.len();
    let grown = end + PROBE_LEN;
    let total = grown.max(ethernet::MIN_FRAME_LEN);
    let length = u16::try_from(grown - start).ok()?;
    if total > out.len() || grown > ethernet::MAX_FRAME_LEN {
        return None;
    }
    out[..end].copy_from_slice(&frame[..end]);
    out[end..total].fill(0);
    if side == Side::Backup {
        let mut eth = EthernetFrame::new_checked(&mut out[..end]).ok()?;
        let mut source = eth.source();
        source[5] ^= BACKUP_MARK;
        eth.set_source(source);
    }
    // The datagrams: the last one gets the M bit, each may be rewritten for its side.
    for (count, datagram) in DatagramsMut::new(&mut out[start..end]).enumerate() {
        let mut datagram = datagram.ok()?;
        let slot = prefer.get_mut(count)?;
        *slot = rewrite(&mut datagram, side, plan);
        if !datagram.more() {
            datagram.set_more(true);
        }
    }
    // The probe: BRD 0x0000, one byte, working counter 0.
    let mut probe = Datagram::new_unchecked(&mut out[end..grown]);
    probe.set_command(Command::Brd);
    probe.set_index(seq);
    probe.set_address(0);
    probe.set_len_flags(1);
    probe.set_irq(0);
    probe.data_mut().fill(0);
    probe.set_wkc(0);
    // The EtherCAT header's length now covers the probe (type 1, datagrams).
    let header = start - crate::wire::frame::HEADER_LEN;
    let raw = (frame_header(&frame[header..start]) & !0x07FF) | length;
    out[header..start].copy_from_slice(&raw.to_le_bytes());
    Some(total)
}

fn frame_header(bytes: &[u8]) -> u16 {
    u16::from_le_bytes([bytes[0], bytes[1]])
}

/// Rewrites one datagram of a copy as its side needs; says where its data is taken from.
fn rewrite(datagram: &mut Datagram<&mut [u8]>, side: Side, plan: &Plan<'_>) -> Prefer {
    let command = datagram.command();
    let broken = plan.state == RingState::Broken;
    if command == Command::Frmw {
        if !broken {
            if side == Side::Backup {
                datagram.set_command(Command::Nop);
            }
            return Prefer::Changed;
        }
        return reference_time(datagram, side, plan);
    }
    if side == Side::Backup && command.addressing() == AddressingMode::Position {
        if broken {
            datagram.set_adp(datagram.adp().wrapping_add(plan.backup_first));
        } else {
            datagram.set_command(Command::Nop);
        }
    }
    Prefer::Changed
}

/// The reference-time datagram of a broken ring, for `side`.
fn reference_time(datagram: &mut Datagram<&mut [u8]>, side: Side, plan: &Plan<'_>) -> Prefer {
    let on_primary = |position: u16| position < plan.primary_side;
    let on_backup = |position: u16| position >= plan.backup_first;
    let reference = plan
        .clocks
        .iter()
        .find(|clock| clock.station == datagram.adp());
    let Some(reference) = reference else {
        // No plan (or another station): as the bus built it.
        return Prefer::Changed;
    };
    let here = match side {
        Side::Primary => on_primary(reference.position),
        Side::Backup => on_backup(reference.position),
    };
    let reachable = on_primary(reference.position) || on_backup(reference.position);
    if here {
        return match side {
            Side::Primary => Prefer::Primary,
            Side::Backup => Prefer::Backup,
        };
    }
    // This side's own first clock in the order the copy passes its slaves (both sides
    // process in rising position order).
    let local = plan
        .clocks
        .iter()
        .filter(|clock| match side {
            Side::Primary => on_primary(clock.position),
            Side::Backup => on_backup(clock.position),
        })
        .min_by_key(|clock| clock.position);
    match local {
        Some(clock) => datagram.set_adp(clock.station),
        None => datagram.set_command(Command::Nop),
    }
    match (reachable, side) {
        // The reference answers on the other side: its time is the one to report.
        (true, Side::Primary) => Prefer::Backup,
        (true, Side::Backup) => Prefer::Primary,
        // The reference is gone: the primary side's stand-in, else the backup's.
        (false, _) if plan.clocks.iter().any(|c| on_primary(c.position)) => Prefer::Primary,
        (false, _) => Prefer::Backup,
    }
}

/// Which copy a returned frame is, from its source MAC.
pub(crate) fn side_of(frame: &[u8], primary_source: [u8; 6]) -> Option<Side> {
    let eth = EthernetFrame::new_checked(frame).ok()?;
    let mut source = eth.source();
    let mut expected = primary_source;
    source[0] &= !RETURNED_BIT;
    expected[0] &= !RETURNED_BIT;
    if source == expected {
        return Some(Side::Primary);
    }
    expected[5] ^= BACKUP_MARK;
    (source == expected).then_some(Side::Backup)
}

/// The source MAC of a frame the bus built.
pub(crate) fn source_of(frame: &[u8]) -> Option<[u8; 6]> {
    EthernetFrame::new_checked(frame)
        .ok()
        .map(|eth| eth.source())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::command::DatagramAddress;
    use crate::wire::datagram::DatagramRepr;
    use crate::wire::frame::FrameBuilder;

    const SOURCE: [u8; 6] = [2, 0, 0, 0, 0, 1];

    fn frame(datagrams: &[(Command, DatagramAddress, &[u8])]) -> Vec<u8> {
        let mut buf = vec![0u8; ethernet::MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        for (i, (command, address, data)) in datagrams.iter().enumerate() {
            builder
                .push(&DatagramRepr::request(*command, i as u8, *address, data))
                .unwrap();
        }
        let len = builder.finish(SOURCE).unwrap();
        buf.truncate(len);
        buf
    }

    fn datagrams(frame: &[u8]) -> Vec<(Command, u8, u16, u16, u16)> {
        let parsed = EthercatFrame::parse(frame).unwrap();
        parsed
            .datagrams()
            .unwrap()
            .map(|d| {
                let d = d.unwrap();
                let adp = (d.address & 0xFFFF) as u16;
                (d.command, d.index, adp, d.data.len() as u16, d.wkc)
            })
            .collect()
    }

    fn copy(frame: &[u8], side: Side, plan: &Plan<'_>) -> (Vec<u8>, [Prefer; MAX_DATAGRAMS]) {
        let mut out = vec![0u8; ethernet::MAX_FRAME_LEN];
        let mut prefer = [Prefer::Changed; MAX_DATAGRAMS];
        let len = build(frame, side, plan, 7, &mut out, &mut prefer).unwrap();
        out.truncate(len);
        (out, prefer)
    }

    const CLOCKS: [RingClock; 2] = [
        RingClock {
            position: 0,
            station: 0x1001,
        },
        RingClock {
            position: 5,
            station: 0x1006,
        },
    ];

    fn sample() -> Vec<u8> {
        frame(&[
            (
                Command::Frmw,
                DatagramAddress::Node {
                    station: 0x1001,
                    ado: 0x0910,
                },
                &[0; 8],
            ),
            (Command::Aprd, DatagramAddress::position(6, 0x0130), &[0; 2]),
            (Command::Lrw, DatagramAddress::Logical(0x1_0000), &[0xAA; 4]),
        ])
    }

    #[test]
    fn both_copies_end_with_the_probe_and_only_the_backup_is_marked() {
        let plan = Plan {
            state: RingState::Closed,
            primary_side: 8,
            backup_first: 8,
            clocks: &CLOCKS,
        };
        let (primary, _) = copy(&sample(), Side::Primary, &plan);
        let (backup, _) = copy(&sample(), Side::Backup, &plan);
        let seen = datagrams(&primary);
        assert_eq!(seen.len(), 4);
        assert_eq!(seen[3], (Command::Brd, 7, 0, 1, 0), "the probe, numbered");
        assert_eq!(seen[0].0, Command::Frmw);
        assert_eq!(side_of(&primary, SOURCE), Some(Side::Primary));
        assert_eq!(side_of(&backup, SOURCE), Some(Side::Backup));
        // With the ring closed the backup copy cannot address anyone by position, nor
        // write a reference time.
        let seen = datagrams(&backup);
        assert_eq!(seen[0].0, Command::Nop);
        assert_eq!(seen[1].0, Command::Nop);
        assert_eq!(seen[2].0, Command::Lrw, "process data goes both ways");
    }

    #[test]
    fn a_broken_ring_shifts_positions_and_gives_the_far_side_its_own_reference() {
        // Break after 3 slaves of 8: positions 3.. are served from the backup port.
        let plan = Plan {
            state: RingState::Broken,
            primary_side: 3,
            backup_first: 3,
            clocks: &CLOCKS,
        };
        let (primary, prefer_p) = copy(&sample(), Side::Primary, &plan);
        let (backup, prefer_b) = copy(&sample(), Side::Backup, &plan);
        let p = datagrams(&primary);
        let b = datagrams(&backup);
        assert_eq!(
            (p[0].0, p[0].2),
            (Command::Frmw, 0x1001),
            "reference on this side"
        );
        assert_eq!(
            (b[0].0, b[0].2),
            (Command::Frmw, 0x1006),
            "the far side's first clock"
        );
        assert_eq!(prefer_p[0], Prefer::Primary);
        assert_eq!(prefer_b[0], Prefer::Primary);
        // Position 6 is the 4th slave the backup copy meets: ADP -6 + 3 = -3.
        assert_eq!(p[1].2, 0u16.wrapping_sub(6));
        assert_eq!(b[1].2, 0u16.wrapping_sub(3));
    }

    #[test]
    fn a_side_without_a_clock_gets_no_reference_time() {
        let plan = Plan {
            state: RingState::Broken,
            primary_side: 3,
            backup_first: 3,
            clocks: &CLOCKS[..1],
        };
        let (backup, _) = copy(&sample(), Side::Backup, &plan);
        assert_eq!(datagrams(&backup)[0].0, Command::Nop);
    }

    #[test]
    fn frames_that_are_not_ours_are_not_copied() {
        let mut out = vec![0u8; ethernet::MAX_FRAME_LEN];
        let mut prefer = [Prefer::Changed; MAX_DATAGRAMS];
        let plan = Plan {
            state: RingState::Unknown,
            primary_side: 0,
            backup_first: 0,
            clocks: &[],
        };
        let mut ip = sample();
        ip[12..14].copy_from_slice(&[0x08, 0x00]);
        assert_eq!(
            build(&ip, Side::Primary, &plan, 0, &mut out, &mut prefer),
            None
        );
        assert_eq!(
            build(&[0; 10], Side::Primary, &plan, 0, &mut out, &mut prefer),
            None
        );
    }
}
