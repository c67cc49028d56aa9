//! A frame's datagram chain, walked once for all the slaves it passes.
//!
//! Every ESC processes the same datagrams at the same places (a slave changes data, ADP,
//! IRQ and working counter, never a length), so the chain's layout is read once per frame
//! and each slave works on the datagrams at those places. A chain that turns malformed
//! stops every slave at the same datagram, which each counts as a processing unit error,
//! as it did when each walked the chain itself.

use ecat_wire::datagram::{Datagram, DatagramsMut};

/// Where each datagram of a payload lies, and whether the walk ended at a malformed one.
#[derive(Debug, Default, Clone)]
pub struct Chain {
    /// Start and length in the payload of each well-formed datagram, in order.
    spans: Vec<(usize, usize)>,
    malformed: bool,
}

impl Chain {
    /// Reads the layout of `payload` (the bytes after the EtherCAT header), reusing this
    /// chain's storage.
    pub fn read(&mut self, payload: &mut [u8]) {
        self.spans.clear();
        self.malformed = false;
        // A real ESC ignores the reserved length bits; KickCAT leaves them uninitialised.
        let mut walk = DatagramsMut::ignoring_reserved_bits(payload);
        loop {
            let start = walk.offset();
            match walk.next() {
                Some(Ok(datagram)) => self.spans.push((start, datagram.total_len())),
                Some(Err(_)) => {
                    self.malformed = true;
                    break;
                }
                None => break,
            }
        }
    }

    /// The chain of `payload`, newly allocated.
    pub fn of(payload: &mut [u8]) -> Chain {
        let mut chain = Chain::default();
        chain.read(payload);
        chain
    }

    /// The datagrams of `payload` at the places read, in order. `payload` must be the one
    /// read (or one of its length with the same layout); a place outside it is skipped.
    pub fn datagrams<'p>(
        &'p self,
        payload: &'p mut [u8],
    ) -> impl Iterator<Item = Datagram<&'p mut [u8]>> + 'p {
        let mut rest: &'p mut [u8] = payload;
        let mut at = 0usize;
        self.spans.iter().filter_map(move |&(start, len)| {
            let skip = start.checked_sub(at)?;
            let taken = std::mem::take(&mut rest);
            let (_, tail) = taken.split_at_mut_checked(skip)?;
            let (head, tail) = tail.split_at_mut_checked(len)?;
            rest = tail;
            at = start + len;
            Some(Datagram::new_unchecked(head))
        })
    }

    /// Whether the walk ended at a malformed datagram (after those in [`Self::datagrams`]).
    pub fn malformed(&self) -> bool {
        self.malformed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ecat_wire::command::Command;
    use ecat_wire::datagram::DatagramRepr;

    /// Two datagrams (BRD of 2 bytes, then FPRD of 4), the first with M set.
    fn two() -> Vec<u8> {
        let first = DatagramRepr {
            command: Command::Brd,
            index: 1,
            address: 0x0130_0000,
            data: &[0, 0],
            circulating: false,
            more: true,
            irq: 0,
            wkc: 0,
        };
        let second = DatagramRepr {
            command: Command::Fprd,
            index: 2,
            address: 0x0010_03E9,
            data: &[0; 4],
            more: false,
            ..first
        };
        let split = first.buffer_len();
        let mut payload = vec![0u8; split + second.buffer_len()];
        first
            .emit(&mut Datagram::new_unchecked(&mut payload[..split]))
            .unwrap();
        second
            .emit(&mut Datagram::new_unchecked(&mut payload[split..]))
            .unwrap();
        payload
    }

    #[test]
    fn every_datagram_is_found_where_the_walk_found_it() {
        let mut payload = two();
        let chain = Chain::of(&mut payload);
        assert!(!chain.malformed());
        let found: Vec<(Command, u8, usize)> = chain
            .datagrams(&mut payload)
            .map(|d| (d.command(), d.index(), d.data().len()))
            .collect();
        assert_eq!(found, vec![(Command::Brd, 1, 2), (Command::Fprd, 2, 4)]);
    }

    #[test]
    fn a_chain_cut_short_keeps_the_datagrams_before_the_cut_and_says_so() {
        let mut payload = two();
        // The second datagram loses its last bytes: M of the first promises more.
        payload.truncate(payload.len() - 3);
        let chain = Chain::of(&mut payload);
        assert!(chain.malformed());
        assert_eq!(chain.datagrams(&mut payload).count(), 1);
        let mut empty: [u8; 0] = [];
        let chain = Chain::of(&mut empty);
        assert!(chain.malformed(), "an empty payload is no datagram chain");
        assert_eq!(chain.datagrams(&mut empty).count(), 0);
    }
}
