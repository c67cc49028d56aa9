//! The EoE receiver of one slave: fragments in, Ethernet frames out (spec-notes §eoe), with a
//! deadline for the next fragment so a lost one does not hold a partial frame forever.

use std::time::{Duration, Instant};

use crate::mailbox::engine::hook::{Pushed, Reassembly};
use crate::wire::eoe::{EoeFrameType, EoePacket, FragmentRepr, Reassembler};

/// Reassembly state of one slave.
///
/// A lost frame is counted once (spec-notes §eoe): when its partial frame is dropped (a part refused, overdue, or a new frame
/// begun before its last part came), or, when its first part never came, at its first
/// later part; the parts after that are orphans of a frame already counted.
#[derive(Debug)]
pub(crate) struct EoeRx {
    reassembler: Reassembler,
    last_fragment: Instant,
    timeout: Duration,
    /// A frame was counted as lost and no new frame has begun since.
    lost: bool,
}

impl EoeRx {
    pub fn new(timeout: Duration) -> EoeRx {
        EoeRx {
            reassembler: Reassembler::default(),
            last_fragment: Instant::now(),
            timeout,
            lost: false,
        }
    }

    /// Drops a partial frame that can no longer complete: its next fragment is overdue, or
    /// `next` is the first fragment of a new frame. True if one was dropped.
    pub fn expire(&mut self, now: Instant, next: Option<&[u8]>) -> bool {
        if !self.reassembler.in_progress() {
            return false;
        }
        let overdue = now.duration_since(self.last_fragment) > self.timeout;
        if overdue || next.is_some_and(starts_a_frame) {
            self.reassembler.reset();
            self.lost = true;
            return true;
        }
        false
    }

    /// Takes one EoE message of frame type 0 or 1 (mailbox data); call [`Self::expire`]
    /// first. Timestamp responses carry no frame and are ignored.
    pub fn push(&mut self, data: &[u8], now: Instant) -> Pushed {
        let Ok(packet) = EoePacket::new_checked(data) else {
            return self.refuse();
        };
        if packet.frame_type() != EoeFrameType::Fragment {
            return Pushed::Ignored;
        }
        let Ok(fragment) = FragmentRepr::parse(&packet) else {
            return self.refuse();
        };
        self.last_fragment = now;
        if fragment.fragment_number == 0 {
            self.lost = false;
        }
        match self.reassembler.push(&fragment) {
            Ok(Some(frame)) => Pushed::Frame(frame.frame.to_vec()),
            Ok(None) => Pushed::Partial,
            Err(_) => self.refuse(),
        }
    }

    /// A message that fits no frame: the frame in progress (or the one it belongs to) is
    /// lost, counted once.
    fn refuse(&mut self) -> Pushed {
        self.reassembler.reset();
        if std::mem::replace(&mut self.lost, true) {
            Pushed::Orphan
        } else {
            Pushed::Dropped
        }
    }
}

/// Whether `data` is an EoE fragment that begins a frame (fragment number 0).
fn starts_a_frame(data: &[u8]) -> bool {
    EoePacket::new_checked(data)
        .ok()
        .filter(|packet| packet.frame_type() == EoeFrameType::Fragment)
        .and_then(|packet| {
            FragmentRepr::parse(&packet)
                .ok()
                .map(|f| f.fragment_number == 0)
        })
        .unwrap_or(false)
}

/// The engine routes EoE fragments here through its hook.
impl Reassembly for EoeRx {
    fn expire(&mut self, now: Instant, next: Option<&[u8]>) -> bool {
        EoeRx::expire(self, now, next)
    }

    fn push(&mut self, data: &[u8], now: Instant) -> Pushed {
        EoeRx::push(self, data, now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Emit;
    use crate::wire::eoe::{EoeRepr, Fragmenter};

    fn fragments(frame: &[u8], frame_number: u8) -> Vec<Vec<u8>> {
        Fragmenter::new(frame, 64, frame_number)
            .unwrap()
            .map(|f| EoeRepr::Fragment(f).to_vec().unwrap())
            .collect()
    }

    #[test]
    fn a_frame_whose_next_fragment_is_late_is_dropped() {
        let frame: Vec<u8> = (0..150u8).collect();
        let parts = fragments(&frame, 3);
        assert_eq!(parts.len(), 4, "32 bytes per fragment in a 64-byte mailbox");
        let start = Instant::now();
        let mut rx = EoeRx::new(Duration::from_millis(100));
        assert_eq!(rx.push(&parts[0], start), Pushed::Partial);
        assert_eq!(rx.push(&parts[1], start), Pushed::Partial);
        let late = start + Duration::from_millis(150);
        assert!(
            rx.expire(late, Some(&parts[2])),
            "the partial frame is dropped"
        );
        assert_eq!(
            rx.push(&parts[2], late),
            Pushed::Orphan,
            "no frame in progress, and its loss is counted already"
        );
        // The next frame goes through whole.
        let again = fragments(&frame, 4);
        let results: Vec<_> = again.iter().map(|p| rx.push(p, late)).collect();
        assert_eq!(results.last(), Some(&Pushed::Frame(frame.clone())));
        assert!(
            !rx.expire(late + Duration::from_secs(10), None),
            "nothing in progress"
        );
    }

    /// Pushes the fragments as the engine does (`expire` with the next one first) and
    /// returns the frames put together and the lost frames counted.
    fn feed(rx: &mut EoeRx, parts: &[&Vec<u8>]) -> (Vec<Vec<u8>>, u32) {
        let now = Instant::now();
        let (mut frames, mut lost) = (Vec::new(), 0);
        for part in parts {
            if rx.expire(now, Some(part)) {
                lost += 1;
            }
            match rx.push(part, now) {
                Pushed::Frame(frame) => frames.push(frame),
                Pushed::Dropped => lost += 1,
                Pushed::Partial | Pushed::Orphan | Pushed::Ignored => {}
            }
        }
        (frames, lost)
    }

    #[test]
    fn a_lost_fragment_costs_one_frame_counted_once_wherever_it_was() {
        let first: Vec<u8> = (0..150u8).collect();
        let second: Vec<u8> = (100..250u8).collect();
        let a = fragments(&first, 1);
        let b = fragments(&second, 2);
        assert_eq!(a.len(), 4);
        for missing in 0..a.len() {
            let mut rx = EoeRx::new(Duration::from_secs(1));
            let parts: Vec<&Vec<u8>> = a
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != missing)
                .map(|(_, p)| p)
                .chain(b.iter())
                .collect();
            let (frames, lost) = feed(&mut rx, &parts);
            assert_eq!(
                frames,
                std::slice::from_ref(&second),
                "fragment {missing} of 4 missing"
            );
            assert_eq!(lost, 1, "fragment {missing} of 4 missing");
        }
    }

    #[test]
    fn whole_frames_count_nothing() {
        let frame: Vec<u8> = (0..150u8).collect();
        let (a, b) = (fragments(&frame, 1), fragments(&frame, 2));
        let mut rx = EoeRx::new(Duration::from_secs(1));
        let (frames, lost) = feed(&mut rx, &a.iter().chain(b.iter()).collect::<Vec<_>>());
        assert_eq!((frames.len(), lost), (2, 0));
    }
}
