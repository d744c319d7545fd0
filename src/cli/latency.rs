//! `photopose latency`: how long frames and poses take through the running service.
//! It subscribes to `photopose/stereo_frames`, `photopose/poses` and (when present)
//! `photopose/truth`, woken by their events, and reports frame transport (publish →
//! receive), estimation (capture → pose published) and end to end (capture → pose
//! received), dropped frames and the pose stream's jitter. `--compare-transport`
//! instead sends the same HD side-by-side frames over iceoryx2 and over a Unix domain
//! socket and compares the two.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use iceoryx2::prelude::*;
use serde::Serialize;

use crate::cli::report::plot::{self, Panel, Series, PALETTE};
use crate::cli::report::stats::Samples;
use crate::transport::ipc::{receive_poses, Ipc};
use crate::transport::messages::{monotonic_ns, FrameHeader, PoseMsg, FRAMES_SERVICE, POSES_SERVICE};

/// Measure the latency of the running service.
#[derive(clap::Args, Debug)]
pub struct LatencyArgs {
    /// How long to listen (or, with --compare-transport, how many seconds of frames to
    /// send at 60 fps).
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Also write one line per pose (CSV: frame_id, capture_time_ns, publish_time_ns,
    /// received_ns, estimation_ms, end_to_end_ms, transport_us).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Also write a latency histogram and time series (PNG).
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Compare iceoryx2 with a copying transport (a Unix domain socket) on HD frames.
    #[arg(long)]
    pub compare_transport: bool,
}

/// Listens for `--seconds` and reports (or compares the transports), writing the CSV
/// and the plot when asked.
pub fn run(args: &LatencyArgs) -> Result<()> {
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        return Err(anyhow!("--seconds {} must be a positive number", args.seconds));
    }
    if args.compare_transport {
        return compare_transport(args);
    }
    let observed = observe(args.seconds)?;
    if observed.poses.is_empty() {
        return Err(anyhow!(nothing_heard(observed.frames.len(), args.seconds)));
    }
    let report = observed.report();
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!("{}", report.text());
    }
    if let Some(path) = &args.csv {
        let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        observed
            .write_csv(BufWriter::new(file))
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(path) = &args.plot {
        plot::save(&observed.plot()?, path)?;
    }
    Ok(())
}

/// Why there is nothing to report after `seconds` in which `frames` frames and no pose
/// arrived: which process is missing (the figures would all be undefined).
fn nothing_heard(frames: usize, seconds: f64) -> String {
    match frames {
        0 => {
            format!("no frames and no poses in {seconds} s: start `photopose capture` and `photopose estimator` first")
        }
        n => format!("{n} frames but no poses in {seconds} s: is `photopose estimator` running?"),
    }
}

/// A pose as the tool saw it.
#[derive(Debug, Clone, Copy)]
struct Seen {
    pose: PoseMsg,
    received_ns: u64,
}

/// Column names of `--csv`, in the order of [`PoseRow`]'s fields.
const CSV_HEADER: [&str; 7] = [
    "frame_id",
    "capture_time_ns",
    "publish_time_ns",
    "received_ns",
    "estimation_ms",
    "end_to_end_ms",
    "transport_us",
];

/// One line of `--csv`: a pose's times, its latencies (ms, to the µs) and its frame's
/// transport time (µs, to 0.1 µs; empty when the frame was not seen).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[cfg_attr(test, derive(serde::Deserialize))]
struct PoseRow {
    frame_id: u64,
    capture_time_ns: u64,
    publish_time_ns: u64,
    received_ns: u64,
    estimation_ms: f64,
    end_to_end_ms: f64,
    transport_us: Option<f64>,
}

/// `v` rounded to `n` decimals, so the CSV carries no false precision.
fn decimals(v: f64, n: i32) -> f64 {
    let scale = 10f64.powi(n);
    (v * scale).round() / scale
}

/// Everything observed: frames (id → publish, receive time) and poses.
#[derive(Default)]
struct Observed {
    frames: BTreeMap<u64, (u64, u64)>,
    poses: Vec<Seen>,
    seconds: f64,
}

/// Listens for `seconds`, woken by the frame and pose events.
fn observe(seconds: f64) -> Result<Observed> {
    let ipc = Ipc::new("photopose-latency")?;
    let frames = ipc.frame_subscriber()?;
    let poses = ipc.pose_subscriber(POSES_SERVICE)?;
    let (frame_wake, pose_wake) = (ipc.wake(FRAMES_SERVICE)?, ipc.wake(POSES_SERVICE)?);
    let waitset = WaitSetBuilder::new()
        .create::<ipc::Service>()
        .map_err(|e| anyhow!("cannot create a wait set: {e:?}"))?;
    let _guards = [&frame_wake, &pose_wake].map(|l| waitset.attach_notification(l));
    let mut seen = Observed {
        seconds,
        ..Default::default()
    };
    let start = Instant::now();
    while start.elapsed().as_secs_f64() < seconds && ipc.wait(Duration::ZERO) {
        let left = Duration::from_secs_f64((seconds - start.elapsed().as_secs_f64()).max(0.0));
        let _ = waitset
            .wait_and_process_once_with_timeout(|_| CallbackProgression::Continue, left.min(Duration::from_millis(50)));
        // Consume the events; the samples themselves are drained below.
        for wake in [&frame_wake, &pose_wake] {
            let _ = wake.try_wait(|_| {});
        }
        while let Some(frame) = frames.receive().map_err(|e| anyhow!("cannot receive a frame: {e:?}"))? {
            let now = monotonic_ns();
            let h: FrameHeader = *frame.user_header();
            seen.frames.insert(h.frame_id, (h.publish_time_ns, now));
        }
        while let Some(set) = receive_poses(&poses)? {
            // Every object of a set shares the frame's times.
            if let Some(&pose) = set.first() {
                seen.poses.push(Seen {
                    pose,
                    received_ns: monotonic_ns(),
                });
            }
        }
    }
    Ok(seen)
}

/// p50, p90, p99, p99.9 and max of some samples, in one unit.
#[derive(Debug, Clone, Copy, Serialize)]
struct Spread {
    p50: f64,
    p90: f64,
    p99: f64,
    p99_9: f64,
    max: f64,
}

impl Spread {
    fn of(s: &Samples) -> Self {
        Self {
            p50: s.median(),
            p90: s.percentile(90.0),
            p99: s.percentile(99.0),
            p99_9: s.percentile(99.9),
            max: s.max(),
        }
    }

    fn line(&self, unit: &str) -> String {
        format!(
            "p50 {:.3} | p90 {:.3} | p99 {:.3} | p99.9 {:.3} | max {:.3} {unit}",
            self.p50, self.p90, self.p99, self.p99_9, self.max
        )
    }
}

/// What `--json` prints (and the text report shows).
#[derive(Debug, Serialize)]
struct Report {
    seconds: f64,
    frames: usize,
    poses: usize,
    dropped_frames: u64,
    skipped_while_acquiring: u64,
    /// Poses of an object being (re)acquired, left out of the latency figures.
    acquisitions: usize,
    acquisition_max_ms: f64,
    transport_p50_us: f64,
    transport_p99_us: f64,
    estimation_p50_ms: f64,
    estimation_p99_ms: f64,
    end_to_end_p50_ms: f64,
    end_to_end_p99_ms: f64,
    end_to_end_max_ms: f64,
    pose_interval_mean_ms: f64,
    pose_jitter_ms: f64,
    transport_us: Spread,
    estimation_ms: Spread,
    end_to_end_ms: Spread,
    pose_interval_ms: Spread,
}

impl Report {
    fn acquisition_line(&self) -> String {
        match self.acquisitions {
            0 => "no acquisition in this window".into(),
            n => format!(
                "{n} poses while (re)acquiring (up to {:.0} ms each, {} frames skipped meanwhile; left out below)",
                self.acquisition_max_ms, self.skipped_while_acquiring
            ),
        }
    }

    fn text(&self) -> String {
        format!(
            "{:.1} s: {} frames, {} poses, {} frames dropped while tracking\n\
             {}\n\
             frame transport (publish → receive):   {}\n\
             estimation (capture → pose published):  {}\n\
             end to end (capture → pose received):   {}\n\
             pose stream: interval mean {:.2} ms, jitter (std) {:.2} ms, {}",
            self.seconds,
            self.frames,
            self.poses,
            self.dropped_frames,
            self.acquisition_line(),
            self.transport_us.line("µs"),
            self.estimation_ms.line("ms"),
            self.end_to_end_ms.line("ms"),
            self.pose_interval_mean_ms,
            self.pose_jitter_ms,
            self.pose_interval_ms.line("ms")
        )
    }
}

impl Observed {
    fn ms(ns: u64) -> f64 {
        ns as f64 * 1e-6
    }

    /// The median generations of the poses with an estimate: a window mostly spent
    /// acquiring would otherwise have a median of 0 and count every tracking pose as an
    /// acquisition ([`Self::acquiring`]).
    fn tracking_generations(&self) -> f64 {
        let estimated = self.poses.iter().filter(|p| p.pose.generations > 0);
        Samples::new(estimated.map(|p| p.pose.generations as f64)).median()
    }

    /// True for a pose of an object being (re)acquired: published while its search ran
    /// in the background (no generations), or one that searched the whole frame itself
    /// (more generations than `tracking_generations`, the tracking poses' median).
    fn acquiring(p: &Seen, tracking_generations: f64) -> bool {
        p.pose.generations == 0 || p.pose.generations as f64 > tracking_generations
    }

    /// The tracking poses (acquisitions left out), `median` the
    /// [`Self::tracking_generations`].
    fn tracking(&self, median: f64) -> impl Iterator<Item = &Seen> {
        self.poses.iter().filter(move |p| !Self::acquiring(p, median))
    }

    /// Frames without a pose between consecutive poses: (while tracking, after an
    /// acquisition), `median` the [`Self::tracking_generations`].
    fn dropped(&self, median: f64) -> (u64, u64) {
        let (mut tracking, mut acquiring) = (0, 0);
        for w in self.poses.windows(2) {
            let gap = w[1].pose.frame_id.saturating_sub(w[0].pose.frame_id + 1);
            if Self::acquiring(&w[0], median) {
                acquiring += gap;
            } else {
                tracking += gap;
            }
        }
        (tracking, acquiring)
    }

    fn report(&self) -> Report {
        let median = self.tracking_generations();
        let transport = Samples::new(
            self.frames
                .values()
                .map(|&(sent, got)| got.saturating_sub(sent) as f64 * 1e-3),
        );
        let estimation = Samples::new(
            self.tracking(median)
                .map(|p| Self::ms(p.pose.publish_time_ns.saturating_sub(p.pose.capture_time_ns))),
        );
        let end_to_end = Samples::new(
            self.tracking(median)
                .map(|p| Self::ms(p.received_ns.saturating_sub(p.pose.capture_time_ns))),
        );
        let acquisitions = Samples::new(
            self.poses
                .iter()
                .filter(|p| Self::acquiring(p, median))
                .map(|p| Self::ms(p.pose.publish_time_ns.saturating_sub(p.pose.capture_time_ns))),
        );
        let intervals: Vec<f64> = self
            .poses
            .windows(2)
            .map(|w| Self::ms(w[1].pose.publish_time_ns.saturating_sub(w[0].pose.publish_time_ns)))
            .collect();
        let interval = Samples::new(intervals.iter().copied());
        let mean = interval.mean();
        let jitter = (intervals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / intervals.len().max(1) as f64).sqrt();
        let (dropped, skipped) = self.dropped(median);
        Report {
            seconds: self.seconds,
            frames: self.frames.len(),
            poses: self.poses.len(),
            dropped_frames: dropped,
            skipped_while_acquiring: skipped,
            acquisitions: acquisitions.len(),
            acquisition_max_ms: acquisitions.max(),
            transport_p50_us: transport.median(),
            transport_p99_us: transport.percentile(99.0),
            estimation_p50_ms: estimation.median(),
            estimation_p99_ms: estimation.percentile(99.0),
            end_to_end_p50_ms: end_to_end.median(),
            end_to_end_p99_ms: end_to_end.percentile(99.0),
            end_to_end_max_ms: end_to_end.max(),
            pose_interval_mean_ms: mean,
            pose_jitter_ms: jitter,
            transport_us: Spread::of(&transport),
            estimation_ms: Spread::of(&estimation),
            end_to_end_ms: Spread::of(&end_to_end),
            pose_interval_ms: Spread::of(&interval),
        }
    }

    /// Writes one CSV row per pose ([`PoseRow`]) after the header line.
    fn write_csv<W: Write>(&self, out: W) -> csv::Result<()> {
        let mut csv = csv::WriterBuilder::new().has_headers(false).from_writer(out);
        csv.write_record(CSV_HEADER)?;
        for p in &self.poses {
            csv.serialize(PoseRow {
                frame_id: p.pose.frame_id,
                capture_time_ns: p.pose.capture_time_ns,
                publish_time_ns: p.pose.publish_time_ns,
                received_ns: p.received_ns,
                estimation_ms: decimals(
                    Self::ms(p.pose.publish_time_ns.saturating_sub(p.pose.capture_time_ns)),
                    3,
                ),
                end_to_end_ms: decimals(Self::ms(p.received_ns.saturating_sub(p.pose.capture_time_ns)), 3),
                transport_us: self
                    .frames
                    .get(&p.pose.frame_id)
                    .map(|&(sent, got)| decimals(got.saturating_sub(sent) as f64 * 1e-3, 1)),
            })?;
        }
        csv.flush()?;
        Ok(())
    }

    /// A histogram of the end-to-end latency above its time series (and estimation's).
    fn plot(&self) -> Result<image::RgbImage, plot::PlotError> {
        let t0 = self.poses.first().map(|p| p.pose.capture_time_ns).unwrap_or(0);
        let median = self.tracking_generations();
        let series = |f: &dyn Fn(&Seen) -> u64| -> Vec<(f64, f64)> {
            self.tracking(median)
                .map(|p| (p.pose.capture_time_ns.saturating_sub(t0) as f64 * 1e-9, Self::ms(f(p))))
                .collect()
        };
        let end_to_end = series(&|p| p.received_ns.saturating_sub(p.pose.capture_time_ns));
        let estimation = series(&|p| p.pose.publish_time_ns.saturating_sub(p.pose.capture_time_ns));
        let values: Vec<f64> = end_to_end.iter().map(|p| p.1).collect();
        let histogram = plot::histogram(
            "end to end: capture → pose received",
            "latency [ms]",
            &values,
            40,
            PALETTE[0],
        );
        let time = Panel {
            title: "latency per pose",
            x_label: "time [s]",
            y_label: "latency [ms]",
            series: vec![
                Series {
                    label: "end to end",
                    points: &end_to_end,
                    color: PALETTE[0],
                },
                Series {
                    label: "estimation",
                    points: &estimation,
                    color: PALETTE[1],
                },
            ],
            ..Default::default()
        };
        plot::panels(&[histogram, time], 1200, 800)
    }
}

/// Bytes of an HD side-by-side RGB8 frame.
const HD_FRAME: usize = 2 * 1280 * 720 * 3;

/// Sends `seconds × 60` HD frames over iceoryx2 and over a Unix domain socket, each
/// timed from just before sending to just after the receiver has it.
fn compare_transport(args: &LatencyArgs) -> Result<()> {
    let n = ((args.seconds * 60.0).round() as usize).max(10);
    let shm = Samples::new(iceoryx2_transport(n)?);
    let uds = Samples::new(socket_transport(n)?);
    let ratio = uds.median() / shm.median();
    if args.json {
        #[derive(Serialize)]
        struct Compare {
            frames: usize,
            frame_bytes: usize,
            iceoryx2_us: Spread,
            unix_socket_us: Spread,
            ratio_p50: f64,
        }
        let c = Compare {
            frames: n,
            frame_bytes: HD_FRAME,
            iceoryx2_us: Spread::of(&shm),
            unix_socket_us: Spread::of(&uds),
            ratio_p50: ratio,
        };
        println!("{}", serde_json::to_string(&c)?);
    } else {
        println!("{n} HD side-by-side frames ({HD_FRAME} bytes) each way, publish → received:");
        println!("  iceoryx2 (zero-copy):      {}", Spread::of(&shm).line("µs"));
        println!("  Unix domain socket (copy): {}", Spread::of(&uds).line("µs"));
        println!("  the copying transport is {ratio:.0}× slower at p50");
    }
    Ok(())
}

/// Microseconds from just before each send to the receiver holding the frame, over a
/// private iceoryx2 service. The receiver polls without sleeping (so does the socket's),
/// so the figures are the transports' own cost, not the scheduler's wake-up.
fn iceoryx2_transport(n: usize) -> Result<Vec<f64>> {
    const SERVICE: &str = "photopose/latency/probe";
    let ipc = Ipc::new("photopose-latency-probe")?;
    let service = ipc.frames_on(SERVICE)?;
    let subscriber = service
        .subscriber_builder()
        .buffer_size(2)
        .create()
        .map_err(|e| anyhow!("cannot subscribe to {SERVICE}: {e:?}"))?;
    let received = std::thread::scope(|s| -> Result<Vec<f64>> {
        let sender = s.spawn(|| -> Result<()> {
            let ipc = Ipc::new("photopose-latency-probe-sender")?;
            let publisher = ipc
                .frames_on(SERVICE)?
                .publisher_builder()
                .initial_max_slice_len(HD_FRAME)
                .create()
                .map_err(|e| anyhow!("cannot publish on {SERVICE}: {e:?}"))?;
            for i in 0..n {
                // The frame is written in place, as a camera source does, into a
                // sample that is not zeroed first.
                let mut sample = publisher
                    .loan_slice_uninit(HD_FRAME)
                    .map_err(|e| anyhow!("cannot loan a frame: {e:?}"))?
                    .write_from_fn(|_| i as u8);
                sample.user_header_mut().frame_id = i as u64;
                sample.user_header_mut().publish_time_ns = monotonic_ns();
                sample.send().map_err(|e| anyhow!("cannot send: {e:?}"))?;
                std::thread::sleep(Duration::from_micros(16_667));
            }
            Ok(())
        });
        let mut times = Vec::with_capacity(n);
        let deadline = Instant::now() + Duration::from_secs_f64(n as f64 / 60.0 + 5.0);
        while times.len() < n && Instant::now() < deadline {
            match subscriber.receive().map_err(|e| anyhow!("cannot receive: {e:?}"))? {
                Some(frame) => {
                    let now = monotonic_ns();
                    times.push(now.saturating_sub(frame.user_header().publish_time_ns) as f64 * 1e-3);
                }
                None => std::hint::spin_loop(),
            }
        }
        sender.join().map_err(|_| anyhow!("the iceoryx2 sender failed"))??;
        Ok(times)
    })?;
    Ok(received)
}

/// Microseconds from just before each write to the receiver having read the whole frame
/// into its own buffer, over a Unix domain socket pair.
fn socket_transport(n: usize) -> Result<Vec<f64>> {
    let (mut tx, mut rx) = UnixStream::pair().context("cannot create a Unix socket pair")?;
    std::thread::scope(|s| -> Result<Vec<f64>> {
        let sender = s.spawn(move || -> Result<()> {
            let mut frame = vec![0u8; HD_FRAME];
            for i in 0..n {
                frame.fill(i as u8);
                tx.write_all(&monotonic_ns().to_le_bytes())?;
                tx.write_all(&frame)?;
                std::thread::sleep(Duration::from_micros(16_667));
            }
            Ok(())
        });
        let mut frame = vec![0u8; HD_FRAME];
        let mut stamp = [0u8; 8];
        let mut times = Vec::with_capacity(n);
        rx.set_nonblocking(true).context("socket setup")?;
        for _ in 0..n {
            spin_read(&mut rx, &mut stamp)?;
            spin_read(&mut rx, &mut frame)?;
            times.push(monotonic_ns().saturating_sub(u64::from_le_bytes(stamp)) as f64 * 1e-3);
        }
        sender.join().map_err(|_| anyhow!("the socket sender failed"))??;
        Ok(times)
    })
}

/// Fills `buf` from a non-blocking socket, polling without sleeping.
fn spin_read(rx: &mut UnixStream, buf: &mut [u8]) -> Result<()> {
    let mut at = 0;
    while at < buf.len() {
        match rx.read(&mut buf[at..]) {
            Ok(0) => return Err(anyhow!("socket closed")),
            Ok(n) => at += n,
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => std::hint::spin_loop(),
            Err(e) => return Err(e).context("socket receive"),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(frame_id: u64, capture_ns: u64, publish_ns: u64, received_ns: u64) -> Seen {
        Seen {
            pose: PoseMsg {
                frame_id,
                capture_time_ns: capture_ns,
                publish_time_ns: publish_ns,
                ..Default::default()
            },
            received_ns,
        }
    }

    #[test]
    fn a_window_mostly_acquiring_still_counts_its_tracking_poses() {
        let mut observed = Observed::default();
        // Six answers while a search runs in the background, then four tracking frames
        // of 6 generations and one relocation of 12.
        let generations = [0, 0, 0, 0, 0, 0, 12, 6, 6, 6, 6];
        observed.poses = (0..)
            .zip(generations)
            .map(|(i, g)| {
                let mut p = seen(i, i * 1_000, i * 1_000 + 500, i * 1_000 + 600);
                p.pose.generations = g;
                p
            })
            .collect();
        let tracking: Vec<u64> = observed
            .tracking(observed.tracking_generations())
            .map(|p| p.pose.frame_id)
            .collect();
        assert_eq!(tracking, [7, 8, 9, 10]);
    }

    #[test]
    fn csv_has_one_row_per_pose_under_the_header() {
        let mut observed = Observed::default();
        observed.frames.insert(7, (1_000_000, 1_012_345));
        observed.poses = vec![
            seen(7, 1_000_000, 3_500_400, 4_000_000),
            seen(8, 2_000_000, 4_000_000, 5_123_456),
        ];
        let mut out = Vec::new();
        observed.write_csv(&mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            [
                "frame_id,capture_time_ns,publish_time_ns,received_ns,estimation_ms,end_to_end_ms,transport_us",
                "7,1000000,3500400,4000000,2.5,3.0,12.3",
                "8,2000000,4000000,5123456,2.0,3.123,",
            ]
        );
        let rows: Vec<PoseRow> = csv::Reader::from_reader(text.as_bytes())
            .deserialize()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!((rows[0].transport_us, rows[1].transport_us), (Some(12.3), None));
        assert_eq!(rows[1].end_to_end_ms, 3.123);
    }
}
