//! The EoE receiver of one slave: fragments in, Ethernet frames out (spec-notes §eoe), with a
//! deadline for the next fragment so a lost one does not hold a partial frame forever.

use std::time::{Duration, Instant};

use crate::mailbox::engine::hook::{Pushed, Reassembly};
use crate::wire::eoe::{EoeFrameType, EoePacket, FragmentRepr, Reassembler};

/// Reassembly state of one slave.
#[derive(Debug)]
pub(crate) struct EoeRx {
    reassembler: Reassembler,
    last_fragment: Instant,
    timeout: Duration,
}

impl EoeRx {
    pub fn new(timeout: Duration) -> EoeRx {
        EoeRx {
            reassembler: Reassembler::default(),
            last_fragment: Instant::now(),
            timeout,
        }
    }

    /// Drops a partial frame whose next fragment is overdue; true if one was dropped.
    pub fn expire(&mut self, now: Instant) -> bool {
        if self.reassembler.in_progress() && now.duration_since(self.last_fragment) > self.timeout {
            self.reassembler.reset();
            return true;
        }
        false
    }

    /// Takes one EoE message of frame type 0 or 1 (mailbox data); call [`Self::expire`]
    /// first. Timestamp responses carry no frame and are ignored.
    pub fn push(&mut self, data: &[u8], now: Instant) -> Pushed {
        let Ok(packet) = EoePacket::new_checked(data) else {
            return Pushed::Dropped;
        };
        if packet.frame_type() != EoeFrameType::Fragment {
            return Pushed::Ignored;
        }
        let Ok(fragment) = FragmentRepr::parse(&packet) else {
            self.reassembler.reset();
            return Pushed::Dropped;
        };
        self.last_fragment = now;
        match self.reassembler.push(&fragment) {
            Ok(Some(frame)) => Pushed::Frame(frame.frame.to_vec()),
            Ok(None) => Pushed::Partial,
            Err(_) => Pushed::Dropped,
        }
    }
}

/// The engine routes EoE fragments here through its hook.
impl Reassembly for EoeRx {
    fn expire(&mut self, now: Instant) -> bool {
        EoeRx::expire(self, now)
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
        assert!(rx.expire(late), "the partial frame is dropped");
        assert_eq!(
            rx.push(&parts[2], late),
            Pushed::Dropped,
            "no frame in progress"
        );
        // The next frame goes through whole.
        let again = fragments(&frame, 4);
        let results: Vec<_> = again.iter().map(|p| rx.push(p, late)).collect();
        assert_eq!(results.last(), Some(&Pushed::Frame(frame.clone())));
        assert!(
            !rx.expire(late + Duration::from_secs(10)),
            "nothing in progress"
        );
    }
}
