//! Frames the estimator could not use, counted per reason and logged rate-limited: the
//! first of each reason at once, then at most one line per reason every
//! [`LOG_EVERY`] with the count since the last line, so a broken camera cannot flood
//! the log or slow the loop.

use std::fmt::Display;
use std::time::{Duration, Instant};

use crate::transport::messages::FrameFault;

/// Least time between two log lines of one reason.
pub const LOG_EVERY: Duration = Duration::from_secs(5);

/// Reasons: the [`FrameFault`] kinds, then frames the tracker rejected (e.g. a size the
/// calibration does not cover).
const REASONS: usize = FrameFault::KINDS.len() + 1;
const UNUSABLE: usize = FrameFault::KINDS.len();

fn reason_name(i: usize) -> &'static str {
    FrameFault::KINDS.get(i).copied().unwrap_or("not usable")
}

/// Skipped frames per reason.
#[derive(Debug, Default)]
pub struct FrameSkips {
    counts: [u64; REASONS],
    /// Skips since the last log line, and when that line was written.
    unlogged: [u64; REASONS],
    logged: [Option<Instant>; REASONS],
}

impl FrameSkips {
    /// Counts a frame whose header disagrees with its payload.
    pub fn fault(&mut self, frame_id: u64, fault: &FrameFault) {
        self.skip(frame_id, fault.index(), fault);
    }

    /// Counts a well-formed frame the tracker could not use.
    pub fn unusable(&mut self, frame_id: u64, why: &dyn Display) {
        self.skip(frame_id, UNUSABLE, why);
    }

    fn skip(&mut self, frame_id: u64, reason: usize, why: &dyn Display) {
        self.counts[reason] += 1;
        self.unlogged[reason] += 1;
        let now = Instant::now();
        if self.logged[reason].is_some_and(|t| now.duration_since(t) < LOG_EVERY) {
            return;
        }
        let n = std::mem::take(&mut self.unlogged[reason]);
        tracing::warn!("estimator: frame {frame_id} skipped: {why} ({n} such frame(s) since the last report)");
        self.logged[reason] = Some(now);
    }

    /// `"none"`, or the counts per reason: `"3 wrong length, 1 unknown pixel format"`.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = (0..REASONS)
            .filter(|&i| self.counts[i] > 0)
            .map(|i| format!("{} {}", self.counts[i], reason_name(i)))
            .collect();
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(", ")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_per_reason_and_logs_each_reason_once_per_period() {
        let mut skips = FrameSkips::default();
        assert_eq!(skips.summary(), "none");
        let wrong = FrameFault::LengthMismatch {
            len: 1,
            expected: 2,
            height: 1,
            stride: 2,
        };
        for id in 0..5 {
            skips.fault(id, &wrong);
        }
        skips.fault(9, &FrameFault::UnknownPixelFormat { code: 7 });
        skips.unusable(10, &"size not calibrated");
        assert_eq!(skips.counts.iter().sum::<u64>(), 7);
        assert_eq!(skips.summary(), "1 unknown pixel format, 5 wrong length, 1 not usable");
        // The first of each reason was logged; the other four wait for the next line.
        assert_eq!(skips.unlogged[FrameFault::KINDS.len() - 1], 4);
        assert_eq!(skips.unlogged[0], 0);
    }
}
