//! Slave groups: sets of slaves whose process data goes at a period of their own.
//!
//! Every slave not given to a group belongs to the default group 0, exchanged every cycle
//! (the master's cycle period). A group defined with [`Master::set_groups`](crate::master::Master::set_groups)
//! gets its own share of the image, its own logical address range (group *g* at
//! `g × 0x1000`), its own LRW, sent every round(period / cycle period) cycles, and its own
//! counters ([`GroupStats`]) and snapshots. Groups take effect at the next scan.

use std::time::Duration;

/// A group of slaves with its own period, for [`Master::set_groups`](crate::master::Master::set_groups).
///
/// Its slaves get their own share of the image, their own logical range (group *g* from
/// `g × 0x1000`) and their own LRW, sent every round(period / cycle period) cycles; every
/// slave not in a group stays in the default group 0, exchanged every cycle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveGroup {
    /// Ring positions of its slaves. A slave listed in two groups belongs to the first.
    pub positions: Vec<u16>,
    /// How often its process data is exchanged: rounded to a whole number of cycle periods,
    /// at least one.
    pub period: Duration,
}

/// What one group's exchange has done since the last scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GroupStats {
    /// The group's number (0: the default group).
    pub group: usize,
    /// Its period (`None`: every cycle, the default group).
    pub period: Option<Duration>,
    /// Logical address of its image share.
    pub logical: u32,
    /// Offset of its share in the image (what entries' offsets count from).
    pub image_offset: usize,
    /// Bytes of its share.
    pub image_len: usize,
    /// Its LRW datagrams sent.
    pub sent: u64,
    /// Its LRW datagrams that came back.
    pub completed: u64,
    /// Working counter of its last exchange.
    pub last_wkc: u16,
    /// The working counter it should have.
    pub expected_wkc: u16,
    /// Exchanges whose working counter was not the expected one.
    pub wrong_wkc: u64,
}

/// The group each of `count` positions belongs to (0: the default group), given the
/// definitions: the first group listing a position takes it.
pub(crate) fn membership(definitions: &[SlaveGroup], count: usize) -> Vec<usize> {
    let mut group = vec![0; count];
    for (index, definition) in definitions.iter().enumerate().rev() {
        for &position in &definition.positions {
            if let Some(slot) = group.get_mut(usize::from(position)) {
                *slot = index + 1;
            }
        }
    }
    group
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unlisted_slaves_stay_in_the_default_group_and_the_first_listing_wins() {
        let period = Duration::from_millis(4);
        let definitions = vec![
            SlaveGroup {
                positions: vec![1, 3, 9],
                period,
            },
            SlaveGroup {
                positions: vec![3, 4],
                period,
            },
        ];
        assert_eq!(membership(&definitions, 5), vec![0, 1, 0, 1, 2]);
        assert_eq!(membership(&[], 2), vec![0, 0]);
    }
}
