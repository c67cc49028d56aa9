//! Receiver-side reassembly of EoE fragments into Ethernet frames (ETG.1000.6, spec-notes §eoe).

use thiserror::Error;

use super::fragment::{FragmentRepr, MAX_FRAME_LEN};
use super::header::OFFSET_UNIT;
use crate::WireError;

/// Why a fragment was not accepted. The partial frame (if any) has been dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum ReassemblyError {
    /// A fragment other than 0 arrived while no frame was being reassembled.
    #[error("EoE reassembly: fragment {fragment_number} without a first fragment")]
    NoFrameInProgress {
        /// The fragment number received.
        fragment_number: u8,
    },
    /// The frame number differs from the first fragment's.
    #[error("EoE reassembly: frame number {got}, expected {expected}")]
    FrameNumber {
        /// The frame being reassembled.
        expected: u8,
        /// The frame number received.
        got: u8,
    },
    /// A fragment is missing, repeated or out of order.
    #[error("EoE reassembly: fragment {got}, expected {expected}")]
    FragmentNumber {
        /// The next fragment number.
        expected: u8,
        /// The fragment number received.
        got: u8,
    },
    /// The fragment's offset × 32 is not the number of bytes received so far.
    #[error("EoE reassembly: fragment at offset {got}, expected {expected}")]
    Offset {
        /// Bytes received so far.
        expected: usize,
        /// Offset field × 32.
        got: usize,
    },
    /// The data exceed the size announced by fragment 0 or the reassembler's limit.
    #[error("EoE reassembly: {size} bytes exceed the limit of {limit}")]
    Overflow {
        /// Bytes the frame would have with this fragment.
        size: usize,
        /// The smaller of the announced size and the configured limit.
        limit: usize,
    },
}

impl From<ReassemblyError> for WireError {
    fn from(e: ReassemblyError) -> Self {
        let reason = match e {
            ReassemblyError::NoFrameInProgress { .. } => "fragment without a first fragment",
            ReassemblyError::FrameNumber { .. } => "wrong frame number",
            ReassemblyError::FragmentNumber { .. } => "fragment out of order",
            ReassemblyError::Offset { .. } => "wrong fragment offset",
            ReassemblyError::Overflow { .. } => "frame larger than announced or allowed",
        };
        WireError::Invalid {
            what: "EoE reassembly",
            reason,
        }
    }
}

/// A completely reassembled Ethernet frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReassembledFrame<'a> {
    /// The Ethernet frame (without FCS, without an appended timestamp).
    pub frame: &'a [u8],
    /// Its frame number.
    pub frame_number: u8,
    /// The timestamp appended to the last fragment, if any.
    pub timestamp: Option<u32>,
}

#[derive(Debug, Clone, Copy)]
struct InProgress {
    frame_number: u8,
    next_fragment: u8,
    /// Upper bound for this frame: min(size field × 32, limit).
    bound: usize,
}

/// Reassembles the fragments of one Ethernet frame at a time, in a buffer of bounded size.
///
/// Receiver rules (IgH/SOEM, spec-notes §eoe): fragment 0 starts a new frame (silently dropping
/// any unfinished one, as both do); every later fragment must have the same frame number, the
/// next fragment number, offset × 32 equal to the bytes received, and must not overflow. On
/// any violation the partial frame is dropped and the error returned. The size field of
/// fragment 0 is only an upper bound (IgH announces `len / 32 + 1` units).
#[derive(Debug, Clone)]
pub struct Reassembler {
    buffer: Vec<u8>,
    limit: usize,
    state: Option<InProgress>,
}

impl Default for Reassembler {
    fn default() -> Self {
        Self::new(MAX_FRAME_LEN)
    }
}

impl Reassembler {
    /// A reassembler accepting frames of up to `max_frame_len` bytes (at most
    /// [`MAX_FRAME_LEN`], the largest size the header can announce). The buffer is allocated
    /// once and never grows beyond that.
    pub fn new(max_frame_len: usize) -> Self {
        let limit = max_frame_len.min(MAX_FRAME_LEN);
        Reassembler {
            buffer: Vec::with_capacity(limit),
            limit,
            state: None,
        }
    }

    /// Whether a frame is partially received.
    pub fn in_progress(&self) -> bool {
        self.state.is_some()
    }

    /// Drops any partial frame.
    pub fn reset(&mut self) {
        self.state = None;
        self.buffer.clear();
    }

    /// Adds a fragment; returns the frame when this was its last fragment.
    pub fn push(
        &mut self,
        fragment: &FragmentRepr<'_>,
    ) -> Result<Option<ReassembledFrame<'_>>, ReassemblyError> {
        let state = if fragment.fragment_number == 0 {
            self.reset();
            InProgress {
                frame_number: fragment.frame_number,
                next_fragment: 0,
                bound: (usize::from(fragment.offset_field) * OFFSET_UNIT).min(self.limit),
            }
        } else {
            let Some(state) = self.state else {
                return Err(ReassemblyError::NoFrameInProgress {
                    fragment_number: fragment.fragment_number,
                });
            };
            let check = if fragment.frame_number != state.frame_number {
                Err(ReassemblyError::FrameNumber {
                    expected: state.frame_number,
                    got: fragment.frame_number,
                })
            } else if fragment.fragment_number != state.next_fragment {
                Err(ReassemblyError::FragmentNumber {
                    expected: state.next_fragment,
                    got: fragment.fragment_number,
                })
            } else if usize::from(fragment.offset_field) * OFFSET_UNIT != self.buffer.len() {
                Err(ReassemblyError::Offset {
                    expected: self.buffer.len(),
                    got: usize::from(fragment.offset_field) * OFFSET_UNIT,
                })
            } else {
                Ok(())
            };
            if let Err(e) = check {
                self.reset();
                return Err(e);
            }
            state
        };
        let size = self.buffer.len() + fragment.data.len();
        if size > state.bound {
            self.reset();
            return Err(ReassemblyError::Overflow {
                size,
                limit: state.bound,
            });
        }
        self.buffer.extend_from_slice(fragment.data);
        if fragment.last {
            self.state = None;
            Ok(Some(ReassembledFrame {
                frame: &self.buffer,
                frame_number: state.frame_number,
                timestamp: fragment.timestamp,
            }))
        } else {
            self.state = Some(InProgress {
                next_fragment: state.next_fragment.wrapping_add(1),
                ..state
            });
            Ok(None)
        }
    }
}
