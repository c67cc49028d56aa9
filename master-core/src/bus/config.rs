//! How a bus is set up: timing, retries, queue and frame sizes.

use std::io;
use std::time::Duration;

use crate::wire::datagram::OVERHEAD;
use crate::wire::ethernet::{MAX_FRAME_LEN, MIN_FRAME_LEN};

use super::sched::ThreadPriority;

/// Length of the Ethernet header plus the EtherCAT header in front of the first datagram.
pub(crate) const FRAME_HEADERS_LEN: usize = crate::wire::ethernet::HEADER_LEN + 2;

/// How the bus thread waits for returning frames.
///
/// The link must be set up to match: a [`RawSocket`](crate::link::RawSocket) for busy
/// polling is opened with `RawSocketOptions { busy_poll: true, .. }`, so that its own
/// waiting spins as well.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WaitMode {
    /// Sleep in the link's `recv` until a frame arrives or the next deadline passes. Costs
    /// no CPU while waiting; the wake-up adds a few microseconds of latency.
    #[default]
    Poll,
    /// Never sleep: ask the link for frames without waiting, over and over. The lowest
    /// latency, at the price of one CPU core spinning for as long as the bus runs (also when
    /// idle, so that a submission is picked up at once).
    BusyPoll,
}

/// Settings of a bus; see [`Bus::start`](super::Bus::start).
///
/// Use struct update syntax for the fields you care about:
/// `BusConfig { source_mac, ..BusConfig::default() }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusConfig {
    /// Source MAC address of the frames the bus sends (the interface's own address). Slaves
    /// do not care; it shows in captures. Default: `02:00:00:00:00:01`, a locally
    /// administered address.
    pub source_mac: [u8; 6],
    /// How the bus thread waits for returning frames. Default: [`WaitMode::Poll`].
    pub wait_mode: WaitMode,
    /// How long a frame may be away before it counts as lost and is sent again. A real
    /// segment answers within microseconds to a millisecond; the default of 10 ms leaves
    /// room for slow kernels without holding callers long when a frame really is lost.
    pub response_timeout: Duration,
    /// How many times a lost frame is sent again before its datagrams fail with
    /// [`BusError::Timeout`](super::BusError::Timeout). Default: 3 (four tries in all).
    pub retries: u32,
    /// How many datagrams may wait in the submission queue; a submission to a full queue
    /// fails at once with [`BusError::QueueFull`](super::BusError::QueueFull). The queue's
    /// memory is reserved up front. Default: 1024.
    pub queue_capacity: usize,
    /// Longest frame the bus builds, without FCS: 1514 (a 1500-byte MTU) or less for a
    /// link with a smaller MTU. At least 60. Default: 1514.
    pub max_frame_len: usize,
    /// How many acyclic frames may be on the wire at once. More frames in flight keep the
    /// wire busy under load; each one reserves a frame buffer's worth of bookkeeping.
    /// At least 1. Default: 4.
    pub frames_in_flight: usize,
    /// How the bus thread is scheduled. Default: [`ThreadPriority::Inherit`]; ask for
    /// [`ThreadPriority::Realtime`] to keep cycles on time while other threads load every
    /// core.
    pub priority: ThreadPriority,
    /// How long before each cycle is due the bus thread wakes, to spin until it is due. A
    /// sleeping thread is woken late by the kernel: tens of µs on a virtual machine or a
    /// core leaving an idle state, more with the other cores busy. Waking this much early
    /// spends that latency before the cycle is due instead of after, at the price of up to
    /// this much CPU per period. At most half the period is spun. Meant for a real-time bus
    /// thread ([`ThreadPriority::Realtime`]): an ordinary one can be preempted while it
    /// spins. Default: zero, no spinning.
    pub cycle_spin: Duration,
}

impl Default for BusConfig {
    fn default() -> BusConfig {
        BusConfig {
            source_mac: [0x02, 0x00, 0x00, 0x00, 0x00, 0x01],
            wait_mode: WaitMode::Poll,
            response_timeout: Duration::from_millis(10),
            retries: 3,
            queue_capacity: 1024,
            max_frame_len: MAX_FRAME_LEN,
            frames_in_flight: 4,
            priority: ThreadPriority::Inherit,
            cycle_spin: Duration::ZERO,
        }
    }
}

impl BusConfig {
    /// The largest data length one datagram may have in frames of `max_frame_len` bytes
    /// (1486 for the default).
    pub fn max_data_len(&self) -> usize {
        self.max_frame_len
            .min(MAX_FRAME_LEN)
            .saturating_sub(FRAME_HEADERS_LEN + OVERHEAD)
    }

    /// Bytes available for datagrams (headers, data and working counters) in one frame.
    pub(crate) fn datagram_room(&self) -> usize {
        self.max_frame_len
            .min(MAX_FRAME_LEN)
            .saturating_sub(FRAME_HEADERS_LEN)
    }

    /// Refuses settings the bus cannot work with, saying which and why.
    pub(crate) fn check(&self) -> io::Result<()> {
        let invalid = |reason: String| Err(io::Error::new(io::ErrorKind::InvalidInput, reason));
        if !(MIN_FRAME_LEN..=MAX_FRAME_LEN).contains(&self.max_frame_len) {
            return invalid(format!(
                "max_frame_len {} is outside {MIN_FRAME_LEN}..={MAX_FRAME_LEN}",
                self.max_frame_len
            ));
        }
        if self.queue_capacity == 0 {
            return invalid("queue_capacity must be at least 1".into());
        }
        if self.frames_in_flight == 0 {
            return invalid("frames_in_flight must be at least 1".into());
        }
        if self.response_timeout.is_zero() {
            return invalid("response_timeout must be longer than zero".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_frames_carry_the_protocol_maximum_of_1486_data_bytes() {
        let config = BusConfig::default();
        assert_eq!(config.max_data_len(), 1486);
        assert_eq!(config.datagram_room(), 1498);
        config.check().unwrap();
    }

    #[test]
    fn unusable_settings_are_refused() {
        for config in [
            BusConfig {
                max_frame_len: 59,
                ..BusConfig::default()
            },
            BusConfig {
                max_frame_len: 1515,
                ..BusConfig::default()
            },
            BusConfig {
                queue_capacity: 0,
                ..BusConfig::default()
            },
            BusConfig {
                frames_in_flight: 0,
                ..BusConfig::default()
            },
            BusConfig {
                response_timeout: Duration::ZERO,
                ..BusConfig::default()
            },
        ] {
            let err = config.check().unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{config:?}");
        }
    }
}
