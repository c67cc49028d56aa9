//! Two returned copies made into the one frame the bus sent.
//!
//! Per datagram (spec-notes §redundancy): the working counters add up (each slave
//! processed exactly one copy); the IRQ words are OR-ed; the data is taken bit by bit
//! from whichever copy changed it from what was sent. A slave only changes the bits it
//! reads into the frame (its own inputs, its registers, the OR of a broadcast read), and
//! each slave sits on one side, so every changed bit comes from the side of the slave that
//! owns it, whatever the FMMU layout; a bit neither copy changed is the same in both.
//! Re-addressed reference-time datagrams are taken whole from one copy
//! ([`Prefer`]). The frame handed up is the bus's own frame with that data: same
//! commands, addresses and length, no probe, so the bus matches it as it would a frame
//! from a line.

use crate::wire::datagram::{Datagram, DatagramRepr, Datagrams, DatagramsMut};
use crate::wire::frame::EthercatFrame;

use super::copies::{MAX_DATAGRAMS, Prefer};

/// One returned copy: the frame and the probe number it must carry.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Returned<'a> {
    pub frame: &'a [u8],
    pub seq: u8,
}

/// What the probes of the merged copies counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Reach {
    /// Slaves that processed the primary copy, if it came back whole.
    pub primary: Option<u16>,
    /// Slaves that processed the backup copy, if it came back whole.
    pub backup: Option<u16>,
}

/// Merges `primary` and `backup` (either may be missing, or be damaged and then ignored)
/// into `out` after `template`, the frame the bus sent. Returns the merged length and
/// what the probes counted, or `None` if `template` is not an EtherCAT frame or `out` is
/// too short.
pub(crate) fn merge(
    template: &[u8],
    prefer: &[Prefer; MAX_DATAGRAMS],
    primary: Option<Returned<'_>>,
    backup: Option<Returned<'_>>,
    out: &mut [u8],
) -> Option<(usize, Reach)> {
    let parsed = EthercatFrame::parse(template).ok()?;
    let (start, end) = (
        parsed.payload_offset,
        parsed.payload_offset + parsed.payload.len(),
    );
    let out = out.get_mut(..template.len())?;
    out.copy_from_slice(template);
    let primary = primary.and_then(|copy| Copy::check(copy, parsed.payload));
    let backup = backup.and_then(|copy| Copy::check(copy, parsed.payload));
    let reach = Reach {
        primary: primary.as_ref().map(|c| c.probe_wkc),
        backup: backup.as_ref().map(|c| c.probe_wkc),
    };
    // Mark the frame as returned, as the first slave does to every frame it sends back.
    out[6] |= 0x02;
    let mut p = primary.map(|c| Datagrams::new(c.payload));
    let mut b = backup.map(|c| Datagrams::new(c.payload));
    let mut sent = Datagrams::new(parsed.payload);
    for (i, merged) in DatagramsMut::new(&mut out[start..end]).enumerate() {
        let mut merged = merged.ok()?;
        let sent = sent.next()?.ok()?;
        let from_p = p.as_mut().and_then(|it| it.next()).and_then(Result::ok);
        let from_b = b.as_mut().and_then(|it| it.next()).and_then(Result::ok);
        let prefer = prefer.get(i).copied().unwrap_or_default();
        combine(&mut merged, sent.data, from_p, from_b, prefer);
    }
    Some((template.len(), reach))
}

/// One datagram of the merged frame.
fn combine(
    merged: &mut Datagram<&mut [u8]>,
    sent: &[u8],
    p: Option<DatagramRepr<'_>>,
    b: Option<DatagramRepr<'_>>,
    prefer: Prefer,
) {
    let wkc = |d: &Option<DatagramRepr<'_>>| d.as_ref().map_or(0, |d| d.wkc);
    let irq = |d: &Option<DatagramRepr<'_>>| d.as_ref().map_or(0, |d| d.irq);
    merged.set_wkc(wkc(&p).wrapping_add(wkc(&b)));
    merged.set_irq(irq(&p) | irq(&b));
    let whole = match prefer {
        Prefer::Primary => p.as_ref().or(b.as_ref()),
        Prefer::Backup => b.as_ref().or(p.as_ref()),
        Prefer::Changed => None,
    };
    let data = merged.data_mut();
    if let Some(whole) = whole {
        data.copy_from_slice(whole.data);
        return;
    }
    let none: &[u8] = &[];
    let pd = p.as_ref().map_or(none, |d| d.data);
    let bd = b.as_ref().map_or(none, |d| d.data);
    for (i, byte) in data.iter_mut().enumerate() {
        let s = sent.get(i).copied().unwrap_or(0);
        let changed_p = pd.get(i).map_or(0, |v| v ^ s);
        let changed_b = bd.get(i).map_or(0, |v| v ^ s);
        *byte = s ^ (changed_p | changed_b);
    }
}

/// A returned copy checked against the frame sent.
struct Copy<'a> {
    payload: &'a [u8],
    probe_wkc: u16,
}

impl<'a> Copy<'a> {
    /// The copy if it carries the sent datagrams (same indices and lengths, in order) and
    /// then the probe with its number; `None` for anything else (damaged, or an older
    /// frame under the same index).
    fn check(copy: Returned<'a>, sent: &[u8]) -> Option<Copy<'a>> {
        let parsed = EthercatFrame::parse(copy.frame).ok()?;
        let mut returned = Datagrams::new(parsed.payload);
        for sent in Datagrams::new(sent) {
            let sent = sent.ok()?;
            let back = returned.next()?.ok()?;
            if back.index != sent.index || back.data.len() != sent.data.len() {
                return None;
            }
        }
        let probe = returned.next()?.ok()?;
        if probe.index != copy.seq || probe.data.len() != 1 || returned.next().is_some() {
            return None;
        }
        Some(Copy {
            payload: parsed.payload,
            probe_wkc: probe.wkc,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::redundancy::copies::tests::frame;
    use crate::bus::redundancy::copies::{Plan, Side, build};
    use crate::bus::redundancy::status::RingState;
    use crate::wire::command::{Command, DatagramAddress};
    use crate::wire::ethernet;

    /// Plays slaves on a copy: datagram `i` gets `data` OR-ed in and `wkc` added; the probe
    /// counts `slaves`.
    fn process(copy: &mut [u8], edits: &[(usize, &[u8], u16)], slaves: u16) {
        let parsed = EthercatFrame::parse(copy).unwrap();
        let (start, end) = (
            parsed.payload_offset,
            parsed.payload_offset + parsed.payload.len(),
        );
        let all: Vec<_> = DatagramsMut::new(&mut copy[start..end]).collect();
        let n = all.len();
        for (i, d) in all.into_iter().enumerate() {
            let mut d = d.unwrap();
            if i == n - 1 {
                d.set_wkc(slaves);
            }
            for (at, data, wkc) in edits {
                if *at == i {
                    for (byte, v) in d.data_mut().iter_mut().zip(data.iter()) {
                        *byte |= v;
                    }
                    let w = d.wkc();
                    d.set_wkc(w + wkc);
                }
            }
        }
    }

    fn copies(template: &[u8]) -> (Vec<u8>, Vec<u8>, [Prefer; MAX_DATAGRAMS]) {
        let plan = Plan {
            state: RingState::Broken,
            primary_side: 2,
            backup_first: 2,
            clocks: &[],
        };
        let mut prefer = [Prefer::Changed; MAX_DATAGRAMS];
        let mut p = vec![0u8; ethernet::MAX_FRAME_LEN];
        let mut b = vec![0u8; ethernet::MAX_FRAME_LEN];
        let lp = build(template, Side::Primary, &plan, 9, &mut p, &mut prefer).unwrap();
        let lb = build(template, Side::Backup, &plan, 9, &mut b, &mut prefer).unwrap();
        p.truncate(lp);
        b.truncate(lb);
        (p, b, prefer)
    }

    fn data_and_wkc(frame: &[u8]) -> Vec<(Vec<u8>, u16)> {
        EthercatFrame::parse(frame)
            .unwrap()
            .datagrams()
            .unwrap()
            .map(|d| {
                let d = d.unwrap();
                (d.data.to_vec(), d.wkc)
            })
            .collect()
    }

    #[test]
    fn inputs_come_bit_by_bit_from_the_side_that_wrote_them_and_counters_add_up() {
        // An LRW whose byte 1 holds inputs of a slave on each side (bit-wise FMMUs), and a
        // BRD of the AL status answered on both sides.
        let template = frame(&[
            (
                Command::Lrw,
                DatagramAddress::Logical(0x1_0000),
                &[0xF0, 0x00, 0x00],
            ),
            (Command::Brd, DatagramAddress::broadcast(0x0130), &[0, 0]),
            (
                Command::Fprd,
                DatagramAddress::Node {
                    station: 0x1004,
                    ado: 0x0130,
                },
                &[0, 0],
            ),
        ]);
        let (mut p, mut b, prefer) = copies(&template);
        process(
            &mut p,
            &[(0, &[0x00, 0x01, 0x00], 3), (1, &[0x02, 0x00], 2)],
            2,
        );
        process(
            &mut b,
            &[
                (0, &[0x00, 0x80, 0x5A], 3),
                (1, &[0x08, 0x00], 3),
                (2, &[0x08, 0x00], 1),
            ],
            3,
        );
        let mut out = vec![0u8; ethernet::MAX_FRAME_LEN];
        let (len, reach) = merge(
            &template,
            &prefer,
            Some(Returned { frame: &p, seq: 9 }),
            Some(Returned { frame: &b, seq: 9 }),
            &mut out,
        )
        .unwrap();
        assert_eq!(len, template.len(), "the bus's frame, without the probe");
        assert_eq!(
            reach,
            Reach {
                primary: Some(2),
                backup: Some(3)
            }
        );
        let merged = data_and_wkc(&out[..len]);
        assert_eq!(merged[0], (vec![0xF0, 0x81, 0x5A], 6));
        assert_eq!(
            merged[1],
            (vec![0x0A, 0x00], 5),
            "a broadcast read is the OR of all"
        );
        assert_eq!(merged[2], (vec![0x08, 0x00], 1));
    }

    #[test]
    fn a_missing_or_foreign_copy_leaves_the_other_alone() {
        let template = frame(&[(Command::Brd, DatagramAddress::broadcast(0x0130), &[0, 0])]);
        let (mut p, b, prefer) = copies(&template);
        process(&mut p, &[(0, &[0x04, 0x00], 4)], 4);
        let mut out = vec![0u8; ethernet::MAX_FRAME_LEN];
        // The backup copy of another frame (wrong probe number) counts for nothing.
        let (len, reach) = merge(
            &template,
            &prefer,
            Some(Returned { frame: &p, seq: 9 }),
            Some(Returned { frame: &b, seq: 10 }),
            &mut out,
        )
        .unwrap();
        assert_eq!(
            reach,
            Reach {
                primary: Some(4),
                backup: None
            }
        );
        assert_eq!(data_and_wkc(&out[..len])[0], (vec![0x04, 0x00], 4));
        let (len, reach) = merge(&template, &prefer, None, None, &mut out).unwrap();
        assert_eq!(reach, Reach::default());
        assert_eq!(data_and_wkc(&out[..len])[0], (vec![0, 0], 0));
    }
}
