//! Datagram indices: which of the 256 are on the wire, and in which frame.
//!
//! The index is the master's only tag on a datagram (slaves echo it unchanged), so an index
//! is never handed out while a frame carrying it is in flight. Indices are handed out
//! round-robin rather than lowest-first: an index comes back into use only after all the
//! others were used, which keeps a very late reply from looking like the answer to a new
//! request (the frame check in `matching` catches what gets past that).

/// The number of datagram indices (one byte).
pub const INDICES: usize = 256;

/// Which frame record each index belongs to, and which are free.
#[derive(Debug)]
pub(crate) struct IndexTable {
    /// The frame record holding each index, if it is in use.
    owner: [Option<u16>; INDICES],
    /// Where the round-robin search starts.
    next: u8,
    in_use: usize,
}

impl IndexTable {
    pub fn new() -> IndexTable {
        IndexTable {
            owner: [None; INDICES],
            next: 0,
            in_use: 0,
        }
    }

    /// Indices in use.
    pub fn in_use(&self) -> usize {
        self.in_use
    }

    /// Takes a free index for frame record `record`; `None` if all 256 are in flight.
    pub fn take(&mut self, record: u16) -> Option<u8> {
        if self.in_use == INDICES {
            return None;
        }
        // At least one is free, so the search ends within 256 steps.
        loop {
            let index = self.next;
            self.next = self.next.wrapping_add(1);
            let owner = &mut self.owner[usize::from(index)];
            if owner.is_none() {
                *owner = Some(record);
                self.in_use += 1;
                return Some(index);
            }
        }
    }

    /// Gives `index` back.
    pub fn release(&mut self, index: u8) {
        if self.owner[usize::from(index)].take().is_some() {
            self.in_use -= 1;
        }
    }

    /// The frame record that holds `index`, if it is in flight.
    pub fn owner(&self, index: u8) -> Option<u16> {
        self.owner[usize::from(index)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_go_round_robin_and_skip_those_in_flight() {
        let mut table = IndexTable::new();
        assert_eq!(table.take(0), Some(0));
        assert_eq!(table.take(0), Some(1));
        table.release(0);
        // 0 is free again, but comes back only after the rest.
        for expected in 2..=255u8 {
            assert_eq!(table.take(1), Some(expected));
        }
        assert_eq!(table.take(2), Some(0));
        assert_eq!(table.in_use(), 256);
        assert_eq!(table.take(2), None);
        assert_eq!(table.owner(1), Some(0));
        assert_eq!(table.owner(0), Some(2));
        table.release(200);
        table.release(200);
        assert_eq!(table.in_use(), 255);
        assert_eq!(table.take(3), Some(200));
        assert_eq!(table.owner(200), Some(3));
    }
}
