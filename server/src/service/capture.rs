//! Live bus capture to pcapng: frames from the bus's [`CaptureTap`](master_core::link::CaptureTap)
//! for a number of frames or a time, written by a blocking task (never the bus thread) into
//! one pcapng section with one Ethernet interface at nanosecond resolution. The tap's queue
//! is bounded; frames it could not queue are counted, not waited for.

use std::borrow::Cow;
use std::sync::Arc;
use std::time::{Duration, Instant};

use master_core::link::CaptureHub;
use pcap_file::DataLink;
use pcap_file::pcapng::PcapNgWriter;
use pcap_file::pcapng::blocks::enhanced_packet::EnhancedPacketBlock;
use pcap_file::pcapng::blocks::interface_description::{
    InterfaceDescriptionBlock, InterfaceDescriptionOption,
};

use super::{ApiError, Core, Operation, Result, Ticket};

/// The most frames one capture takes.
pub const MAX_FRAMES: u64 = 1_000_000;
/// The longest capture.
pub const MAX_DURATION: Duration = Duration::from_secs(600);
/// The largest capture file (it is sent back whole).
pub const MAX_BYTES: usize = 64 << 20;
/// Frames the tap may queue ahead of the writer.
const QUEUE: usize = 4096;

/// A finished capture.
#[derive(Debug)]
pub struct CaptureResult {
    /// The pcapng file.
    pub pcapng: Vec<u8>,
    /// Frames in it.
    pub frames: u64,
    /// Frames the tap could not queue (the writer fell behind; for the rolling window,
    /// since ecatd started).
    pub dropped: u64,
}

impl Core {
    /// Hands the bus's capture hub to the core.
    pub fn set_capture(&self, hub: Arc<CaptureHub>) {
        let _ = self.capture.set(hub);
    }

    /// Starts the rolling capture over the bus's capture hub (once; at start-up).
    pub fn start_rolling(&self, settings: &crate::config::capture::CaptureSettings) -> Result<()> {
        let hub = self
            .capture
            .get()
            .ok_or_else(|| ApiError::unavailable("this segment has no capture tap"))?;
        let rolling =
            super::rolling::RollingCapture::start(hub, settings).map_err(ApiError::internal)?;
        self.rolling
            .set(rolling)
            .map_err(|_| ApiError::internal("the rolling capture runs already"))
    }

    /// The rolling capture's counters; `None` when it does not run.
    pub fn rolling_stats(&self) -> Option<Arc<super::rolling::RollingStats>> {
        self.rolling.get().map(|r| Arc::clone(r.stats()))
    }

    /// The rolling capture's window: its files, oldest first, as one pcapng file of
    /// several sections (the newest files within [`MAX_BYTES`]).
    pub async fn rolling_window(&self, mut ticket: Ticket) -> Result<CaptureResult> {
        ticket.check(Operation::Capture, "rolling")?;
        let core = self.clone();
        let window = tokio::task::spawn_blocking(move || {
            let rolling = core.rolling.get().ok_or_else(|| {
                let mut err = ApiError::unavailable(
                    "no rolling capture runs: set [capture] rolling = true in ecatd's configuration",
                );
                err.tag = "no_rolling_capture";
                err
            })?;
            let (pcapng, frames) = rolling
                .window(MAX_BYTES)
                .map_err(|err| ApiError::internal(format!("rolling capture: {err}")))?;
            Ok(CaptureResult {
                frames,
                dropped: rolling
                    .stats()
                    .dropped
                    .load(std::sync::atomic::Ordering::Relaxed),
                pcapng,
            })
        })
        .await;
        ticket.finish(
            window.unwrap_or_else(|err| Err(ApiError::internal(format!("capture task: {err}")))),
        )
    }

    /// Captures the bus until `frames` frames (0: no limit) or `duration` (zero: no limit)
    /// have passed, whichever comes first; at least one limit is needed.
    pub async fn capture(
        &self,
        mut ticket: Ticket,
        frames: u64,
        duration: Duration,
    ) -> Result<CaptureResult> {
        ticket.check(Operation::Capture, "all")?;
        ticket.finish(self.capture_frames(frames, duration).await)
    }

    async fn capture_frames(&self, frames: u64, duration: Duration) -> Result<CaptureResult> {
        if frames == 0 && duration.is_zero() {
            return Err(ApiError::invalid_field(
                "frames",
                "give a number of frames, a duration or both",
            ));
        }
        if frames > MAX_FRAMES || duration > MAX_DURATION {
            return Err(ApiError::invalid_field(
                if frames > MAX_FRAMES {
                    "frames"
                } else {
                    "duration"
                },
                format!(
                    "a capture is at most {MAX_FRAMES} frames and {} s",
                    MAX_DURATION.as_secs()
                ),
            ));
        }
        let hub = self
            .capture
            .get()
            .ok_or_else(|| ApiError::unavailable("this segment has no capture tap"))?;
        let capture = hub.open(QUEUE).ok_or_else(|| {
            let mut err =
                ApiError::unavailable("another capture is running; try again when it ends");
            err.tag = "capture_busy";
            err
        })?;
        let limit = if frames == 0 { MAX_FRAMES } else { frames };
        let until = Instant::now()
            + if duration.is_zero() {
                MAX_DURATION
            } else {
                duration
            };
        tokio::task::spawn_blocking(move || {
            let mut writer = PcapNgWriter::new(Vec::new()).map_err(internal)?;
            writer
                .write_pcapng_block(InterfaceDescriptionBlock {
                    linktype: DataLink::ETHERNET,
                    snaplen: 0,
                    // pcap-file writes timestamps in nanoseconds: say so (if_tsresol 9).
                    options: vec![InterfaceDescriptionOption::IfTsResol(9)],
                })
                .map_err(internal)?;
            let mut count = 0;
            while count < limit && writer.get_ref().len() < MAX_BYTES {
                let left = until.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    break;
                }
                let Some(f) = capture.next(left.min(Duration::from_millis(100))) else {
                    continue;
                };
                let len = u32::try_from(f.frame.len()).unwrap_or(u32::MAX);
                writer
                    .write_pcapng_block(EnhancedPacketBlock {
                        interface_id: 0,
                        timestamp: f.at,
                        original_len: len,
                        data: Cow::Owned(f.frame),
                        options: Vec::new(),
                    })
                    .map_err(internal)?;
                count += 1;
            }
            Ok(CaptureResult {
                dropped: capture.dropped(),
                frames: count,
                pcapng: writer.into_inner(),
            })
        })
        .await
        .map_err(|err| ApiError::internal(format!("capture task: {err}")))?
    }
}

fn internal(err: pcap_file::PcapError) -> ApiError {
    ApiError::internal(format!("pcapng: {err}"))
}
