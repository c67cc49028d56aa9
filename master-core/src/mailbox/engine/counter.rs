//! The mailbox counters (spec-notes §mbx.counter): the master's 1..7 sequence for requests, and the
//! check of the slave's counter that spots a message read twice.

/// Counter state of one slave's mailbox.
#[derive(Debug, Clone, Default)]
pub(crate) struct Counters {
    /// Counter of the last request written; 0 before the first.
    tx: u8,
    /// Counter of the last message accepted from the slave, if it numbers its messages.
    last_rx: Option<u8>,
}

impl Counters {
    /// Counters that continue after request counter `tx` (0: start at 1), for an owner that
    /// takes over a mailbox the slave did not reset: the slave still remembers `tx` and
    /// would discard a next request with the same counter as a repetition.
    pub fn continuing_after(tx: u8) -> Counters {
        Counters {
            tx: tx % 8,
            last_rx: None,
        }
    }

    /// The counter for the next request: 1, 2, ..., 7, 1, ... (never 0, so the slave
    /// discards a repetition of the same request, e.g. a bus retry that got through twice).
    pub fn next_tx(&mut self) -> u8 {
        self.tx = self.tx % 7 + 1;
        self.tx
    }

    /// The counter of the last request written (0 before the first).
    pub fn last_tx(&self) -> u8 {
        self.tx
    }

    /// Takes back the counters given out after `last`, the counter of the last request the
    /// slave may have taken: requests composed after it were never written, and the next
    /// gets `last`'s successor. Otherwise seven counters given to writes that never went in
    /// would bring the next one round to the slave's last, and it would discard it as a
    /// repetition.
    pub fn rewind_to(&mut self, last: u8) {
        self.tx = last % 8;
    }

    /// Whether a message with the slave's counter `counter` is new.
    ///
    /// A slave numbers every message it posts 1..7 (0 = it does not count, and nothing can
    /// be checked), so two messages in a row never have the same counter: one that repeats
    /// the last accepted counter is the same message again. That happens after repeat
    /// requests (spec-notes §mbx.repeat): the slave re-posts the message the master read last, which
    /// the master already has when the lost frame was lost before it reached the slave —
    /// and after two repeats in a row a slave may even hand that copy out twice. A slave
    /// that falls back to INIT restarts its count; the master then takes its mailbox over
    /// afresh ([`MailboxEngine::add_slave`](crate::mailbox::MailboxEngine::add_slave)), with new counters.
    pub fn accept_rx(&mut self, counter: u8) -> bool {
        if counter == 0 {
            return true;
        }
        if self.last_rx == Some(counter) {
            return false;
        }
        self.last_rx = Some(counter);
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
    fn a_message_read_again_is_a_duplicate() {
        let mut c = Counters::default();
        assert!(c.accept_rx(3));
        assert!(!c.accept_rx(3), "the re-posted message 3");
        assert!(!c.accept_rx(3), "and once more after a second repeat");
        assert!(c.accept_rx(4));
        assert!(c.accept_rx(5));
        assert!(
            c.accept_rx(0),
            "a slave that does not count cannot be checked"
        );
        assert!(c.accept_rx(0));
        assert!(
            !c.accept_rx(5),
            "the last counted message is still remembered"
        );
    }

    #[test]
    fn counters_given_to_writes_that_never_went_in_are_taken_back() {
        let mut c = Counters::default();
        let last_written = c.next_tx();
        // Seven composed and never written would come round to the slave's last.
        let skipped: Vec<u8> = (0..7).map(|_| c.next_tx()).collect();
        assert_eq!(skipped.last(), Some(&last_written));
        c.rewind_to(last_written);
        assert_eq!(c.last_tx(), last_written);
        assert_eq!(
            c.next_tx(),
            last_written % 7 + 1,
            "the successor of the last written"
        );
    }
}
