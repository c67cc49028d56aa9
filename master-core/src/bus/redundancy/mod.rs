//! Cable redundancy: one segment wired as a ring between two ports of the master
//! (ETG.1000.4 frame processing through the ports, ETG.1000.3; spec-notes §redundancy).
//!
//! [`RingLink`] is a [`Link`] over two links, the primary and the backup port. It sends
//! every frame of the bus out of both ports and hands the bus one frame back per frame
//! sent, made from the two returned copies (`merge`), so the bus above does not know it
//! runs on a ring. What the two copies show goes to a [`RingWatch`]:
//! - **closed**: the copy sent on the primary port comes back on the backup port, having
//!   passed every slave's processing unit; the backup copy comes back on the primary port,
//!   processed by none (a frame entering an ESC's port 1 leaves through its port 0
//!   unprocessed);
//! - **broken**: each copy comes back on its own port, processed by the slaves on its side
//!   of the break (a closed port loops back), so together they still reach every slave
//!   that has power and a path to one of the ports. A probe datagram in each copy counts
//!   the slaves on each side (`copies`), which locates the break.
//!
//! The state is known from every frame, so a break is seen by the first frame after it and
//! a heal likewise, without a rescan. A copy that does not come back (the cable at a
//! master port cut) is waited for at most the link's grace, once: from then on the link
//! expects one copy only, until the other shows up again.
//!
//! A frame is handed up only if it is whole: when a copy is missing and the one that came
//! back was processed by fewer slaves than the ring reached last, the missing copy may hold
//! what the others did (a mailbox read that emptied SM1, a write the slave took), so the
//! frame is not handed up at all and the bus sees it lost, as on a line, and resends it or
//! recovers. Only once nothing came back on the missing copy's way for [`GONE_AFTER`] (the
//! last slave lost power, say) is a short copy taken as the whole frame.

use std::io;
use std::time::{Duration, Instant};

use crate::link::{Link, MAX_FRAME_LEN, Wait, wait_any_readable};
use crate::wire::datagram::Datagrams;
use crate::wire::frame::EthercatFrame;

mod copies;
mod merge;
mod status;

pub use status::{RingClock, RingState, RingStatus, RingWatch};

use copies::{MAX_DATAGRAMS, Plan, Prefer, Side};
use merge::{Reach, Returned};
use status::Observation;

/// How many bytes the ring link adds to each frame (the probe): a bus on a ring builds
/// frames this much shorter than its link's maximum.
pub const RING_OVERHEAD: usize = copies::PROBE_LEN;

/// The longest a returned copy waits for its twin by default: far longer than the two
/// copies of one frame arrive apart on a real ring (the ring's own round trip), far
/// shorter than a cycle the bus could lose.
pub const DEFAULT_GRACE: Duration = Duration::from_micros(500);

/// How long no copy may have come back on one way before a frame whose copy on that way
/// is missing is handed up without it: the slaves that way are then taken to be gone. Far
/// longer than a busy machine holds up one copy (a copy late past the grace comes back
/// all the same, and then the frame handed up without it would have lost what those
/// slaves did); short enough that a slave losing power at the end of the ring costs a
/// handful of cycles at 1 kHz, once.
pub const GONE_AFTER: Duration = Duration::from_millis(10);

/// A frame the bus sent, while its copies are out.
struct Slot {
    active: bool,
    seq: u8,
    /// Frames sent before this one, so that what it shows is not taken over what a later
    /// frame already showed.
    number: u64,
    source: [u8; 6],
    template: Box<[u8]>,
    template_len: usize,
    prefer: [Prefer; MAX_DATAGRAMS],
    /// Which copies went out (primary, backup).
    sent: [bool; 2],
    /// The returned copies: length and the master port each came back on.
    back: [Option<(usize, Side)>; 2],
    bufs: [Box<[u8]>; 2],
    first_back: Option<Instant>,
}

impl Slot {
    fn new() -> Slot {
        let buf = || vec![0u8; MAX_FRAME_LEN].into_boxed_slice();
        Slot {
            active: false,
            seq: 0,
            number: 0,
            source: [0; 6],
            template: buf(),
            template_len: 0,
            prefer: [Prefer::Changed; MAX_DATAGRAMS],
            sent: [false; 2],
            back: [None; 2],
            bufs: [buf(), buf()],
            first_back: None,
        }
    }
}

/// What a received frame was.
enum Accepted {
    /// The copy that completes the frame in this slot.
    Complete(usize),
    /// A copy kept until its twin comes.
    Kept,
    /// A copy of a frame already handed up, or of an older frame under the same index.
    Late,
    /// Not a copy of ours: handed up as it is (the bus counts it).
    Foreign,
}

/// A [`Link`] over the two ports of a ring; see the module documentation.
pub struct RingLink<P: Link, B: Link> {
    primary: P,
    backup: B,
    watch: RingWatch,
    grace: Duration,
    /// By the index of the frame's first datagram (the bus never reuses one in flight).
    slots: Box<[Slot]>,
    rx: Box<[u8]>,
    tx: Box<[u8]>,
    clocks: Vec<status::RingClock>,
    seq: u8,
    /// Frames sent so far.
    sent: u64,
    /// The number of the latest frame whose copies were learned from.
    observed: u64,
    /// Whether each copy (primary, backup) came back last time.
    expect: [bool; 2],
    /// When a copy of each kind (primary, backup) last came back, late ones included.
    last_back: [Option<Instant>; 2],
    /// See [`GONE_AFTER`].
    gone_after: Duration,
}

impl<P: Link, B: Link> std::fmt::Debug for RingLink<P, B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RingLink")
            .field("status", &self.watch.status())
            .field("grace", &self.grace)
            .finish_non_exhaustive()
    }
}

impl<P: Link, B: Link> RingLink<P, B> {
    /// A ring on `primary` and `backup`; a copy waits at most `grace` for its twin.
    pub fn new(primary: P, backup: B, grace: Duration) -> RingLink<P, B> {
        RingLink {
            primary,
            backup,
            watch: RingWatch::default(),
            grace,
            slots: (0..256).map(|_| Slot::new()).collect(),
            rx: vec![0u8; MAX_FRAME_LEN].into_boxed_slice(),
            tx: vec![0u8; MAX_FRAME_LEN].into_boxed_slice(),
            clocks: Vec::new(),
            seq: 0,
            sent: 0,
            observed: 0,
            expect: [true; 2],
            last_back: [None; 2],
            gone_after: GONE_AFTER,
        }
    }

    /// The handle on what this link knows of the ring.
    pub fn watch(&self) -> RingWatch {
        self.watch.clone()
    }

    /// The two links back.
    pub fn into_inner(self) -> (P, B) {
        (self.primary, self.backup)
    }

    fn plan<'c>(&self, clocks: &'c [status::RingClock]) -> Plan<'c> {
        let (state, primary_side, backup_side, ring_slaves) = self.watch.plan();
        // The backup copy is processed from the first slave behind the break; with the
        // ring's size not known, a single break is assumed (it starts right after the
        // primary side).
        let backup_first = if ring_slaves > 0 {
            ring_slaves.saturating_sub(backup_side)
        } else {
            primary_side
        };
        Plan {
            state,
            primary_side,
            backup_first,
            clocks,
        }
    }

    /// Takes the queued frames of both ports until one completes a frame; `Ok(None)` when
    /// both are empty.
    fn drain(&mut self, out: &mut [u8]) -> io::Result<Option<usize>> {
        let mut failed = None;
        let mut any_ok = false;
        for port in [Side::Primary, Side::Backup] {
            loop {
                let got = match port {
                    Side::Primary => self.primary.recv(&mut self.rx, Wait::NoWait),
                    Side::Backup => self.backup.recv(&mut self.rx, Wait::NoWait),
                };
                let len = match got {
                    Ok(Some(len)) => len.min(self.rx.len()),
                    Ok(None) => {
                        any_ok = true;
                        break;
                    }
                    // One dead port (a NIC without link) must not stop the other.
                    Err(err) => {
                        failed.get_or_insert(err);
                        break;
                    }
                };
                any_ok = true;
                match self.accept(port, len) {
                    Accepted::Complete(slot) => {
                        if let Some(len) = self.deliver(slot, out) {
                            return Ok(Some(len));
                        }
                    }
                    Accepted::Kept | Accepted::Late => {}
                    Accepted::Foreign => {
                        let n = len.min(out.len());
                        out[..n].copy_from_slice(&self.rx[..n]);
                        return Ok(Some(n));
                    }
                }
            }
        }
        match failed {
            Some(err) if !any_ok => Err(err),
            _ => Ok(None),
        }
    }

    /// Files the frame in `rx` (`len` bytes), which came back on `port`.
    fn accept(&mut self, port: Side, len: usize) -> Accepted {
        let frame = &self.rx[..len];
        let Ok(parsed) = EthercatFrame::parse(frame) else {
            return Accepted::Foreign;
        };
        let mut datagrams = Datagrams::new(parsed.payload);
        let Some(Ok(first)) = datagrams.next() else {
            return Accepted::Foreign;
        };
        let last_index = Datagrams::new(parsed.payload)
            .last()
            .and_then(Result::ok)
            .map(|d| d.index);
        let slot = &mut self.slots[usize::from(first.index)];
        let Some(side) = copies::side_of(frame, slot.source) else {
            return Accepted::Foreign;
        };
        let which = side as usize;
        let now = Instant::now();
        self.last_back[which] = Some(now);
        // It came back: expect it again. Back on the other port, the ring is closed, so
        // its twin is on its way too (on a heal after a master port's cable was out).
        self.expect[which] = true;
        if port != side {
            self.expect = [true; 2];
        }
        if !slot.active || last_index != Some(slot.seq) || slot.back[which].is_some() {
            return Accepted::Late;
        }
        slot.bufs[which][..len].copy_from_slice(frame);
        slot.back[which] = Some((len, port));
        slot.first_back.get_or_insert(now);
        let waiting = (0..2).any(|c| slot.back[c].is_none() && slot.sent[c] && self.expect[c]);
        if waiting {
            Accepted::Kept
        } else {
            Accepted::Complete(usize::from(first.index))
        }
    }

    /// The slot whose first copy has waited out the grace, if any; and the earliest
    /// moment one will have.
    fn overdue(&self, now: Instant) -> (Option<usize>, Option<Instant>) {
        let mut next = None::<Instant>;
        for (i, slot) in self.slots.iter().enumerate() {
            let Some(first) = slot.first_back.filter(|_| slot.active) else {
                continue;
            };
            let end = first + self.grace;
            if end <= now {
                return (Some(i), None);
            }
            next = Some(next.map_or(end, |n| n.min(end)));
        }
        (None, next)
    }

    /// Merges the copies in `index`'s slot into `out` and learns from them; `None` when
    /// the frame is not whole and must look lost to the bus (see the module documentation).
    fn deliver(&mut self, index: usize, out: &mut [u8]) -> Option<usize> {
        let slot = &mut self.slots[index];
        let ports = [slot.back[0].map(|b| b.1), slot.back[1].map(|b| b.1)];
        // Both back on the backup port: the cable was cut between the two sends. The
        // primary copy passed the whole ring before the cut; the backup copy was processed
        // again by the slaves behind it, so it adds nothing but a second count.
        let cut_between = ports == [Some(Side::Backup), Some(Side::Backup)];
        let copy = |c: usize| {
            slot.back[c].map(|(len, _)| Returned {
                frame: &slot.bufs[c][..len],
                seq: slot.seq,
            })
        };
        let merged = merge::merge(
            &slot.template[..slot.template_len],
            &slot.prefer,
            copy(0),
            copy(1).filter(|_| !cut_between),
            out,
        );
        let sent = slot.sent;
        let missing = [0, 1].map(|c| slot.back[c].is_none() && sent[c]);
        slot.active = false;
        slot.back = [None; 2];
        slot.first_back = None;
        let number = slot.number;
        if missing.contains(&true) {
            self.watch.count_single_return();
        }
        let Some((len, reach)) = merged else {
            return Some(0);
        };
        // The missing copy's way is still there: wait for its copies as before.
        if self.short(sent, reach) {
            self.watch.count_incomplete();
            return None;
        }
        for c in (0..2).filter(|&c| missing[c]) {
            // Not back within the grace: do not wait for it next time.
            self.expect[c] = false;
        }
        // A frame sent before the last one learned from shows an older ring.
        if number > self.observed
            && let Some(seen) = observe(ports, reach)
        {
            self.observed = number;
            self.watch.observe(seen);
        }
        Some(len)
    }

    /// Whether a frame whose copies `sent` (primary, backup) were counted `reach` lacks
    /// what slaves still there did: a copy sent is not counted (missing, or back damaged),
    /// the ring last reached more slaves than the copies counted, and that copy's way is not
    /// gone. (A copy never sent was processed by nobody: the frame shows that as it is.)
    fn short(&self, sent: [bool; 2], reach: Reach) -> bool {
        let lost = [
            sent[0] && reach.primary.is_none(),
            sent[1] && reach.backup.is_none(),
        ];
        if lost == [false; 2] {
            return false;
        }
        let (_, primary_side, backup_side, _) = self.watch.plan();
        let known = primary_side.saturating_add(backup_side);
        let counted = reach
            .primary
            .unwrap_or(0)
            .saturating_add(reach.backup.unwrap_or(0));
        let now = Instant::now();
        let alive = |c: usize| {
            self.last_back[c].is_some_and(|at| now.saturating_duration_since(at) < self.gone_after)
        };
        counted < known && (0..2).any(|c| lost[c] && alive(c))
    }

    /// Waits until a port may have a frame, or `until`.
    fn wait(&self, until: Instant) -> io::Result<()> {
        let now = Instant::now();
        if until <= now {
            return Ok(());
        }
        match (self.primary.wait_fd(), self.backup.wait_fd()) {
            (Some(a), Some(b)) => wait_any_readable(&[a, b], until - now),
            // Links without a descriptor (in-process, memory) are looked at in turns.
            _ => {
                std::thread::yield_now();
                Ok(())
            }
        }
    }
}

/// What the ports the copies came back on and their probes say about the ring.
fn observe(ports: [Option<Side>; 2], reach: Reach) -> Option<Observation> {
    match (ports, reach) {
        (
            [Some(Side::Backup), _],
            Reach {
                primary: Some(slaves),
                ..
            },
        ) => Some(Observation::Closed { slaves }),
        (
            [Some(Side::Primary), back],
            Reach {
                primary: Some(primary),
                backup,
            },
        ) => Some(Observation::Broken {
            primary,
            backup: if back == Some(Side::Backup) {
                backup.unwrap_or(0)
            } else {
                0
            },
        }),
        (
            [None, Some(Side::Backup)],
            Reach {
                backup: Some(backup),
                ..
            },
        ) => Some(Observation::Broken { primary: 0, backup }),
        _ => None,
    }
}

impl<P: Link, B: Link> Link for RingLink<P, B> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        if frame.len() > MAX_FRAME_LEN {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "frame longer than an Ethernet frame",
            ));
        }
        let mut clocks = std::mem::take(&mut self.clocks);
        self.watch.take_clocks(&mut clocks);
        let sent = self.send_copies(frame, &clocks);
        self.clocks = clocks;
        sent
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        loop {
            if let Some(len) = self.drain(buf)? {
                return Ok(Some(len));
            }
            let now = Instant::now();
            let (overdue, next_grace) = self.overdue(now);
            if let Some(slot) = overdue {
                if let Some(len) = self.deliver(slot, buf) {
                    return Ok(Some(len));
                }
                continue;
            }
            let Wait::Until(deadline) = wait else {
                return Ok(None);
            };
            if now >= deadline {
                return Ok(None);
            }
            let until = next_grace.map_or(deadline, |g| g.min(deadline));
            self.wait(until)?;
        }
    }

    fn wait_fd(&self) -> Option<std::os::fd::BorrowedFd<'_>> {
        // Two descriptors cannot be one: a ring is not waited on from outside.
        None
    }
}

impl<P: Link, B: Link> RingLink<P, B> {
    /// Sends the two copies of `frame` and files it under its first datagram's index.
    fn send_copies(&mut self, frame: &[u8], clocks: &[status::RingClock]) -> io::Result<()> {
        let first = EthercatFrame::parse(frame)
            .ok()
            .and_then(|parsed| Datagrams::new(parsed.payload).next())
            .and_then(Result::ok)
            .map(|d| usize::from(d.index));
        let (Some(index), Some(source)) = (first, copies::source_of(frame)) else {
            // Not a datagram frame of ours: out of the primary port as it is.
            return self.primary.send(frame);
        };
        self.seq = self.seq.wrapping_add(1);
        self.sent += 1;
        let (seq, number) = (self.seq, self.sent);
        let mut prefer = [Prefer::Changed; MAX_DATAGRAMS];
        let mut backup_prefer = [Prefer::Changed; MAX_DATAGRAMS];
        let plan = self.plan(clocks);
        let primary_len =
            copies::build(frame, Side::Primary, &plan, seq, &mut self.tx, &mut prefer);
        let Some(primary_len) = primary_len else {
            return self.primary.send(frame);
        };
        let sent_primary = self.primary.send(&self.tx[..primary_len]);
        let backup_len = copies::build(
            frame,
            Side::Backup,
            &plan,
            seq,
            &mut self.tx,
            &mut backup_prefer,
        );
        let sent_backup = match backup_len {
            Some(len) => self.backup.send(&self.tx[..len]),
            None => Err(io::Error::other("no backup copy")),
        };
        for (p, b) in prefer.iter_mut().zip(backup_prefer) {
            if *p == Prefer::Changed {
                *p = b;
            }
        }
        let slot = &mut self.slots[index];
        slot.active = sent_primary.is_ok() || sent_backup.is_ok();
        slot.seq = seq;
        slot.number = number;
        slot.source = source;
        slot.template[..frame.len()].copy_from_slice(frame);
        slot.template_len = frame.len();
        slot.prefer = prefer;
        slot.sent = [sent_primary.is_ok(), sent_backup.is_ok()];
        slot.back = [None; 2];
        slot.first_back = None;
        match (sent_primary, sent_backup) {
            (Err(err), Err(_)) => Err(err),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests;
