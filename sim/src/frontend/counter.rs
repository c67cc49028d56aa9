//! Frames in and out, and a rate line about once per second.

use std::io::{self, Write};
use std::time::{Duration, Instant};

/// How often the rate line is printed.
pub const REPORT_EVERY: Duration = Duration::from_secs(1);

/// Counts frames and tells when a rate line is due.
#[derive(Debug, Clone)]
pub struct FrameCounter {
    /// Frames received.
    pub frames_in: u64,
    /// Frames sent back.
    pub frames_out: u64,
    /// Frames the segment did not return (not EtherCAT, or no slave reachable).
    pub not_returned: u64,
    /// Frames the kernel refused to send (send queue full).
    pub send_dropped: u64,
    last_report: Instant,
    in_at_last_report: u64,
}

impl FrameCounter {
    /// A counter starting at `now`.
    pub fn new(now: Instant) -> Self {
        FrameCounter {
            frames_in: 0,
            frames_out: 0,
            not_returned: 0,
            send_dropped: 0,
            last_report: now,
            in_at_last_report: 0,
        }
    }

    /// If a report is due at `now`, the frames per second received since the last one.
    pub fn due(&mut self, now: Instant) -> Option<f64> {
        let elapsed = now.saturating_duration_since(self.last_report);
        if elapsed < REPORT_EVERY {
            return None;
        }
        let rate = (self.frames_in - self.in_at_last_report) as f64 / elapsed.as_secs_f64();
        self.last_report = now;
        self.in_at_last_report = self.frames_in;
        Some(rate)
    }

    /// Writes the rate line (no allocation: it runs inside the frame loop).
    pub fn write_line(&self, rate: f64, out: &mut impl Write) -> io::Result<()> {
        writeln!(
            out,
            "frames in {} out {} (not returned {}, send dropped {}), {rate:.0} frames/s",
            self.frames_in, self.frames_out, self.not_returned, self.send_dropped
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_once_per_interval_with_the_rate_since_the_last_report() {
        let start = Instant::now();
        let mut counter = FrameCounter::new(start);
        counter.frames_in = 500;
        assert_eq!(counter.due(start + REPORT_EVERY / 2), None);
        assert_eq!(counter.due(start + 2 * REPORT_EVERY), Some(250.0));
        counter.frames_in = 600;
        assert_eq!(counter.due(start + 2 * REPORT_EVERY), None);
        assert_eq!(counter.due(start + 3 * REPORT_EVERY), Some(100.0));
        let mut out = Vec::new();
        counter.write_line(100.0, &mut out).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "frames in 600 out 0 (not returned 0, send dropped 0), 100 frames/s\n"
        );
    }
}
