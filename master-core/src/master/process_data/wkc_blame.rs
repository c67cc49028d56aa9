//! Which slaves a wrong working counter of the cyclic frame is put down to (ETG.1510
//! 0xAnnn:0E).
//!
//! The cyclic frame has one LRW per slave group (the groups due in that cycle) and one LRD of the
//! mailbox-status bits, so a wrong working counter does not name a slave by itself. Each
//! slave's share of both counters is known (LRW: 2 with outputs + 1 with inputs; status:
//! 1 if its bit is mapped), so the shortfall is explained, in this order, by:
//!
//! 1. the shortest tail of the ring whose shares add up to it on both datagrams (the line
//!    broken in front of a slave: it and every slave behind it are missing);
//! 2. else the one slave whose shares equal it (a slave that lost its configuration, or
//!    is in a state that does not serve process data);
//! 3. else every slave that has a share in a datagram that came back wrong.
//!
//! Every slave so blamed counts the cycle once.

/// The share of one slave in the LRW and in the mailbox-status LRD.
fn share(lrw: &[u16], status: &[Option<u16>], position: usize) -> (i64, i64) {
    (
        i64::from(lrw.get(position).copied().unwrap_or(0)),
        i64::from(status.get(position).is_some_and(Option::is_some)),
    )
}

/// Counts one wrong cycle in `counts` (by position) for the slaves that explain the
/// shortfall `deficit` (expected − received working counter of the LRW and of the status
/// LRD; 0 for a datagram that was right or not sent).
pub(crate) fn blame(lrw: &[u16], status: &[Option<u16>], deficit: (i64, i64), counts: &mut [u32]) {
    if deficit == (0, 0) {
        return;
    }
    let n = counts.len();
    let mut bump = |position: usize| {
        if let Some(count) = counts.get_mut(position) {
            *count = count.saturating_add(1);
        }
    };
    // 1. A tail of the ring.
    let mut sum = (0i64, 0i64);
    for start in (0..n).rev() {
        let (l, s) = share(lrw, status, start);
        sum = (sum.0 + l, sum.1 + s);
        if sum == deficit {
            for position in start..n {
                if share(lrw, status, position) != (0, 0) {
                    bump(position);
                }
            }
            return;
        }
    }
    // 2. One slave.
    let mut matching = (0..n).filter(|&p| share(lrw, status, p) == deficit);
    if let (Some(only), None) = (matching.next(), matching.next()) {
        bump(only);
        return;
    }
    // 3. Everyone in a wrong datagram.
    for position in 0..n {
        let (l, s) = share(lrw, status, position);
        if (deficit.0 != 0 && l > 0) || (deficit.1 != 0 && s > 0) {
            bump(position);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // The default segment: drive (outputs + inputs, mailbox), DO8, DI8, CoE store
    // (mailbox), EoE port (mailbox).
    const LRW: [u16; 5] = [3, 2, 1, 0, 0];
    const STATUS: [Option<u16>; 5] = [Some(1001), None, None, Some(1004), Some(1005)];

    fn run(deficit: (i64, i64)) -> [u32; 5] {
        let mut counts = [0u32; 5];
        blame(&LRW, &STATUS, deficit, &mut counts);
        counts
    }

    #[test]
    fn a_broken_line_blames_the_missing_tail() {
        // Unplugged in front of the CoE store: it and the EoE port miss the status read.
        assert_eq!(run((0, 2)), [0, 0, 0, 1, 1]);
        // In front of the DI8: DI8, CoE store and EoE port.
        assert_eq!(run((1, 2)), [0, 0, 1, 1, 1]);
        // Only the last slave.
        assert_eq!(run((0, 1)), [0, 0, 0, 0, 1]);
    }

    #[test]
    fn one_slave_that_lost_its_configuration() {
        assert_eq!(run((2, 0)), [0, 1, 0, 0, 0]);
        assert_eq!(run((3, 1)), [1, 0, 0, 0, 0]);
    }

    #[test]
    fn an_unexplained_shortfall_blames_every_slave_in_the_datagram() {
        assert_eq!(run((4, 0)), [1, 1, 1, 0, 0]);
        assert_eq!(run((-1, 0)), [1, 1, 1, 0, 0]);
        assert_eq!(run((0, 0)), [0; 5]);
    }
}
