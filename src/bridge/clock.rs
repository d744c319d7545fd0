//! From CLOCK_MONOTONIC (the time base of photopose's messages) to CLOCK_REALTIME (ROS
//! stamps): the offset between the two clocks, measured at start and refreshed.

use std::time::{Duration, Instant};

use crate::transport::messages::monotonic_ns;

/// How often the offset is measured again (NTP may slew the real-time clock).
const REFRESH: Duration = Duration::from_secs(2);

/// CLOCK_REALTIME now, ns since the epoch.
pub fn realtime_ns() -> i64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_REALTIME always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_REALTIME, &mut ts) };
    ts.tv_sec * 1_000_000_000 + ts.tv_nsec
}

/// Maps monotonic timestamps to real time.
#[derive(Debug, Clone, Copy)]
pub struct RealtimeMap {
    offset_ns: i64,
    measured: Instant,
}

impl RealtimeMap {
    /// Measures the offset now.
    pub fn new() -> Self {
        Self {
            offset_ns: measure_offset(),
            measured: Instant::now(),
        }
    }

    /// Measures the offset again if the last measurement is older than 2 s.
    pub fn refresh(&mut self) {
        if self.measured.elapsed() >= REFRESH {
            *self = Self::new();
        }
    }

    /// The real time of the monotonic time `monotonic_ns`, ns since the epoch.
    pub fn realtime(&self, monotonic_ns: u64) -> i64 {
        (monotonic_ns as i64).saturating_add(self.offset_ns)
    }
}

impl Default for RealtimeMap {
    fn default() -> Self {
        Self::new()
    }
}

/// realtime − monotonic, ns: of three readings, the one whose real-time read was
/// bracketed most tightly by two monotonic reads.
fn measure_offset() -> i64 {
    (0..3)
        .map(|_| {
            let before = monotonic_ns() as i64;
            let real = realtime_ns();
            let after = monotonic_ns() as i64;
            (after - before, real - before / 2 - after / 2)
        })
        .min_by_key(|&(gap, _)| gap)
        .map_or(0, |(_, offset)| offset)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn now_maps_to_now() {
        let map = RealtimeMap::new();
        let mapped = map.realtime(monotonic_ns());
        let real = realtime_ns();
        assert!((real - mapped).abs() < 5_000_000, "{real} vs {mapped}");
    }
}
