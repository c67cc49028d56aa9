//! Why a datagram did not come back as asked.

use std::io;

use super::request::DatagramResponse;

/// Why a submitted datagram failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// No reply came back, after the configured retries.
    ///
    /// A write may still have been carried out: if only the way back lost the frame, the
    /// slave saw the write and the master cannot tell (see the module docs on retries).
    #[error("no reply after {attempts} attempt(s)")]
    Timeout {
        /// How many times the datagram was sent.
        attempts: u32,
    },
    /// The reply's working counter is not the one the caller expected. The reply is
    /// attached for diagnostics.
    #[error("working counter {got}, expected {expected}")]
    WorkingCounter {
        /// The working counter the caller asked for.
        expected: u16,
        /// The working counter that came back.
        got: u16,
        /// The whole reply.
        response: DatagramResponse,
    },
    /// The bus was shut down before the datagram completed (a datagram that was already
    /// on the wire may have been carried out).
    #[error("the bus was shut down")]
    Shutdown,
    /// The submission queue was full. The queue is sized for the master's worst case, so a
    /// full queue means the bus is overloaded or stuck; failing at once shows it where
    /// waiting would hide it.
    #[error("the bus submission queue is full")]
    QueueFull,
    /// The datagram (or group) does not fit in one frame.
    #[error("{what} needs {need} bytes, a frame has room for {room}")]
    TooLarge {
        /// What did not fit.
        what: &'static str,
        /// Bytes needed.
        need: usize,
        /// Bytes available.
        room: usize,
    },
    /// The request cannot be sent as it is.
    #[error("invalid request: {0}")]
    InvalidRequest(&'static str),
    /// All 256 datagram indices are in flight (seen only by a cyclic task filling its
    /// frame; acyclic datagrams wait for an index instead).
    #[error("all 256 datagram indices are in flight")]
    IndicesExhausted,
    /// Not sent: the datagram of a chain it was to follow did not count or failed
    /// ([`BusHandle::submit_chain`](super::BusHandle::submit_chain)).
    #[error("not sent: the step of its chain before it did not count")]
    Skipped,
    /// The link refused to send the frame on its last attempt (interface down, say).
    #[error("the link failed to send: {0}")]
    Link(io::ErrorKind),
}
