//! The mailbox counters (digest §5.3): the master's 1..7 sequence for requests, and the
//! check of the slave's counter that spots a message read twice after a repeat request.

/// Counter state of one slave's mailbox.
#[derive(Debug, Clone, Default)]
pub(crate) struct Counters {
    /// Counter of the last request written; 0 before the first.
    tx: u8,
    /// Counter of the last message accepted from the slave, if it numbers its messages.
    last_rx: Option<u8>,
    /// The next message read follows a repeat request and may be the one read before.
    after_repeat: bool,
}

impl Counters {
    /// The counter for the next request: 1, 2, ..., 7, 1, ... (never 0, so the slave
    /// discards a repetition of the same request, e.g. a bus retry that got through twice).
    pub fn next_tx(&mut self) -> u8 {
        self.tx = self.tx % 7 + 1;
        self.tx
    }

    /// A repeat request was acknowledged: the slave re-posted the last message it handed
    /// out, which the master may already have (the lost frame may have been lost on its way
    /// out, before the slave saw the read).
    pub fn note_repeat(&mut self) {
        self.after_repeat = true;
    }

    /// Whether a message with the slave's counter `counter` is new. Only right after a
    /// repeat is a message with the same non-zero counter as the last one a duplicate; at
    /// any other time the slave may have restarted its count (a fall back to INIT), so its
    /// messages are taken as they come.
    pub fn accept_rx(&mut self, counter: u8) -> bool {
        let check = std::mem::take(&mut self.after_repeat);
        if check && counter != 0 && self.last_rx == Some(counter) {
            return false;
        }
        if counter != 0 {
            self.last_rx = Some(counter);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_counter_runs_one_to_seven() {
        let mut c = Counters::default();
        let seq: Vec<u8> = (0..9).map(|_| c.next_tx()).collect();
        assert_eq!(seq, [1, 2, 3, 4, 5, 6, 7, 1, 2]);
    }

    #[test]
    fn a_message_read_again_after_a_repeat_is_a_duplicate() {
        let mut c = Counters::default();
        assert!(c.accept_rx(3));
        c.note_repeat();
        assert!(!c.accept_rx(3), "the backup of message 3 again");
        assert!(c.accept_rx(4));
        c.note_repeat();
        assert!(c.accept_rx(5), "the lost message itself");
        assert!(
            c.accept_rx(5),
            "outside a repeat the same counter is accepted"
        );
        c.note_repeat();
        assert!(
            c.accept_rx(0),
            "a slave that does not count cannot be checked"
        );
    }
}
