//! A **test double** thread on the far end of a link that answers like a segment of fake
//! slaves ([`FakeSegment`]), optionally misbehaving as a [`Script`] tells it.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use master_core::link::{Link, MAX_FRAME_LEN, Wait};

use super::segment::FakeSegment;

/// How long the responder waits for a frame before it checks whether to stop and calls
/// [`Script::on_quiet`].
pub const QUIET: Duration = Duration::from_millis(20);

/// What the responder does with each frame. The default answers every frame at once.
pub trait Script: Send + 'static {
    /// A frame arrived (in `frame`, which may be changed in place).
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        answer(frame, segment, link);
    }

    /// No frame arrived for [`QUIET`].
    fn on_quiet(&mut self, _segment: &mut FakeSegment, _link: &mut dyn Link) {}
}

/// Answers every frame at once.
pub struct Answer;

impl Script for Answer {}

/// Runs `frame` through the segment and sends it back; frames that are not datagram
/// frames are dropped, as slaves would not return them either.
pub fn answer(frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
    if segment.process(frame) {
        // A peer that went away is the test's business, not the responder's.
        let _ = link.send(frame);
    }
}

/// What a responder did, handed back when it stops.
#[derive(Debug)]
pub struct Report {
    /// Frames received.
    pub frames: u64,
    /// The segment as the frames left it.
    pub segment: FakeSegment,
}

/// A running responder thread; stops (and is joined) on [`Responder::stop`] or drop.
pub struct Responder {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Report>>,
}

impl Responder {
    /// Starts answering frames from `link` with `segment`, as `script` says.
    pub fn spawn<L: Link + 'static>(
        link: L,
        segment: FakeSegment,
        script: impl Script,
    ) -> Responder {
        let stop = Arc::new(AtomicBool::new(false));
        let thread = std::thread::Builder::new()
            .name("test-responder".into())
            .spawn({
                let stop = Arc::clone(&stop);
                move || run(link, segment, script, &stop)
            })
            .expect("spawn the responder thread");
        Responder {
            stop,
            thread: Some(thread),
        }
    }

    /// Stops the thread and returns what it did.
    pub fn stop(mut self) -> Report {
        self.stop.store(true, Ordering::SeqCst);
        let thread = self.thread.take().expect("joined only here or on drop");
        thread.join().expect("the responder thread panicked")
    }
}

impl Drop for Responder {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            // Never panic in drop; a failed test is already reporting.
            let _ = thread.join();
        }
    }
}

fn run<L: Link>(
    mut link: L,
    mut segment: FakeSegment,
    mut script: impl Script,
    stop: &AtomicBool,
) -> Report {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let mut frames = 0;
    // Ends when asked to, or when the other end of the link is gone (the bus stopped).
    while !stop.load(Ordering::SeqCst) {
        match link.recv(&mut buf, Wait::Until(Instant::now() + QUIET)) {
            Ok(Some(len)) => {
                frames += 1;
                script.on_frame(&mut buf[..len], &mut segment, &mut link);
            }
            Ok(None) => script.on_quiet(&mut segment, &mut link),
            Err(_) => break,
        }
    }
    Report { frames, segment }
}

/// How long a gated responder waits for its gate before it gives up and drops the frame
/// (so that a test whose gate never opens fails with an error instead of hanging).
pub const GATE_PATIENCE: Duration = Duration::from_secs(20);

/// Holds the first frame until the gate is opened (a message on the channel), then answers
/// it and every later frame at once. Frames that arrive meanwhile wait in the link.
pub struct Gated {
    gate: std::sync::mpsc::Receiver<()>,
    open: bool,
}

impl Gated {
    /// The script and the sender that opens its gate.
    pub fn new() -> (Gated, std::sync::mpsc::Sender<()>) {
        let (open, gate) = std::sync::mpsc::channel();
        (Gated { gate, open: false }, open)
    }
}

impl Script for Gated {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        if !self.open {
            self.open = self.gate.recv_timeout(GATE_PATIENCE).is_ok();
            if !self.open {
                return;
            }
        }
        answer(frame, segment, link);
    }
}

/// The datagram indices of every frame seen, in order.
pub type SeenFrames = Arc<std::sync::Mutex<Vec<Vec<u8>>>>;

/// Records the indices of each frame, then lets `inner` handle it.
pub struct Recording<S: Script> {
    inner: S,
    seen: SeenFrames,
}

impl<S: Script> Recording<S> {
    /// Wraps `inner`; the returned list fills as frames arrive.
    pub fn new(inner: S) -> (Recording<S>, SeenFrames) {
        let seen = SeenFrames::default();
        (
            Recording {
                inner,
                seen: Arc::clone(&seen),
            },
            seen,
        )
    }
}

/// The indices of the datagrams in `frame` (empty if it does not parse).
pub fn indices_of(frame: &[u8]) -> Vec<u8> {
    master_core::wire::frame::EthercatFrame::parse(frame)
        .ok()
        .and_then(|parsed| parsed.datagrams().ok())
        .map(|chain| chain.flatten().map(|datagram| datagram.index).collect())
        .unwrap_or_default()
}

impl<S: Script> Script for Recording<S> {
    fn on_frame(&mut self, frame: &mut [u8], segment: &mut FakeSegment, link: &mut dyn Link) {
        self.seen
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(indices_of(frame));
        self.inner.on_frame(frame, segment, link);
    }

    fn on_quiet(&mut self, segment: &mut FakeSegment, link: &mut dyn Link) {
        self.inner.on_quiet(segment, link);
    }
}
