//! `replay:DIR`: plays a recorded [`Sequence`] as a camera would, at its recorded pace or
//! a fixed rate, optionally looping. A reader thread decodes frames ahead into a few
//! recycled buffers; each due frame is copied into the caller's buffer (a loaned
//! sample: decoding straight into it would hold the sample while the file is read).

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::time::Instant;

use crossbeam::channel::{bounded, Receiver, Sender};
use image::codecs::png::PngDecoder;
use image::{ColorType, ImageDecoder};

use super::sequence::{due_offset, Sequence};
use super::{FrameBuf, FrameInfo, FrameSource, Geometry, SourceError, Truth, Written};
use crate::transport::messages::monotonic_ns;
use crate::vision::PixelFormat;

/// Frames decoded ahead of playback.
const AHEAD: usize = 4;

/// A decoded frame: its index in the sequence and its bytes.
type Decoded = Result<(usize, Vec<u8>), SourceError>;

/// A recorded sequence as a frame source.
pub struct ReplaySource {
    dir: PathBuf,
    geometry: Geometry,
    times: Vec<u64>,
    truth: Vec<Option<Truth>>,
    /// The recorded `frame_id`s, and what each pass of a looping replay adds to them
    /// (one more than the largest), so the ids keep increasing.
    ids: Vec<u64>,
    id_period: u64,
    fps: Option<f64>,
    looping: bool,
    start: Instant,
    /// Frames played so far (over all passes).
    played: u64,
    decoded: Receiver<Decoded>,
    recycle: Sender<Vec<u8>>,
}

impl ReplaySource {
    /// Opens `dir`; `fps` overrides the recorded pace.
    pub fn open(dir: &Path, fps: Option<f64>, looping: bool) -> Result<Self, SourceError> {
        let seq = Sequence::open(dir)?;
        let geometry = seq.geometry;
        let (recycle, free) = bounded(AHEAD);
        for _ in 0..AHEAD {
            // Cannot fail: the channel has room for every buffer.
            let _ = recycle.send(vec![0u8; geometry.frame_len()]);
        }
        let (tx, decoded) = bounded(AHEAD);
        let times = seq.times();
        let truth = seq.frames.iter().map(|f| f.truth).collect();
        let ids: Vec<u64> = seq.frames.iter().map(|f| f.frame_id).collect();
        let id_period = ids.iter().max().map_or(1, |m| m.saturating_add(1));
        let reader = seq.clone();
        std::thread::Builder::new()
            .name("photopose-replay".into())
            .spawn(move || read_ahead(&reader, looping, &free, &tx))
            .map_err(|e| SourceError::Setup(format!("cannot start the replay reader: {e}")))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            geometry,
            times,
            truth,
            ids,
            id_period,
            fps,
            looping,
            start: Instant::now(),
            played: 0,
            decoded,
            recycle,
        })
    }
}

/// Decodes the sequence's frames in order (forever when looping) into free buffers until
/// the player goes away or a frame cannot be read (that error is passed on).
fn read_ahead(seq: &Sequence, looping: bool, free: &Receiver<Vec<u8>>, out: &Sender<Decoded>) {
    loop {
        for (i, rec) in seq.frames.iter().enumerate() {
            let Ok(mut buf) = free.recv() else { return };
            let path = seq.dir.join(&rec.file);
            let result = read_frame(&path, seq.geometry, &mut buf).map(|()| (i, buf));
            let failed = result.is_err();
            if out.send(result).is_err() || failed {
                return;
            }
        }
        if !looping {
            return;
        }
    }
}

/// Reads one frame file into `buf` ([`Geometry::frame_len`] bytes).
fn read_frame(path: &Path, geometry: Geometry, buf: &mut [u8]) -> Result<(), SourceError> {
    let problem = |message: String| SourceError::Frame {
        path: path.to_path_buf(),
        message,
    };
    let file = File::open(path).map_err(|e| problem(e.to_string()))?;
    match geometry.format {
        PixelFormat::Rgb8 => {
            let decoder = PngDecoder::new(BufReader::new(file)).map_err(|e| problem(e.to_string()))?;
            let (w, h) = decoder.dimensions();
            if (w, h) != (2 * geometry.width, geometry.height) || decoder.color_type() != ColorType::Rgb8 {
                return Err(problem(format!(
                    "{w}x{h} {:?} image, expected a {}x{} RGB8 side-by-side frame",
                    decoder.color_type(),
                    2 * geometry.width,
                    geometry.height
                )));
            }
            decoder.read_image(buf).map_err(|e| problem(e.to_string()))
        }
        PixelFormat::Yuyv => {
            let len = file.metadata().map_err(|e| problem(e.to_string()))?.len();
            if len != buf.len() as u64 {
                return Err(problem(format!(
                    "{len} bytes, expected {} for a {}x{} YUYV side-by-side frame",
                    buf.len(),
                    2 * geometry.width,
                    geometry.height
                )));
            }
            BufReader::new(file).read_exact(buf).map_err(|e| problem(e.to_string()))
        }
    }
}

impl FrameSource for ReplaySource {
    fn geometry(&self) -> Geometry {
        self.geometry
    }

    fn describe(&self) -> String {
        let pace = match self.fps {
            Some(fps) => format!("{fps} fps"),
            None => "the recorded pace".into(),
        };
        format!(
            "replay of {} ({} frames, {}x{} {} per eye) at {pace}{}",
            self.dir.display(),
            self.times.len(),
            self.geometry.width,
            self.geometry.height,
            self.geometry.format.name(),
            if self.looping { ", looping" } else { "" }
        )
    }

    fn next_due(&mut self) -> Option<Instant> {
        if !self.looping && self.played >= self.times.len() as u64 {
            return None;
        }
        if self.played == 0 {
            self.start = Instant::now();
        }
        Some(self.start + due_offset(&self.times, self.played, self.fps))
    }

    fn write_frame<'a>(&mut self, buf: FrameBuf<'a>) -> Result<Option<(FrameInfo, Written<'a>)>, SourceError> {
        let (index, bytes) = self
            .decoded
            .recv()
            .map_err(|_| SourceError::Setup(format!("the replay reader of {} stopped", self.dir.display())))??;
        let frame = buf.copy_from(&bytes)?;
        // The reader may be gone after the last frame; the buffer is then not needed.
        let _ = self.recycle.send(bytes);
        let pass = self.played / self.ids.len().max(1) as u64;
        self.played += 1;
        let mut info = FrameInfo::single(monotonic_ns(), self.truth[index]);
        info.frame_id = Some(self.ids[index].saturating_add(pass.saturating_mul(self.id_period)));
        Ok(Some((info, frame)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::sequence::{CSV_HEADER, FRAMES_FILE, INFO_FILE};

    /// A two-frame YUYV recording (2×1 pixels per eye) whose frames are numbered 5 and 9.
    fn recording(dir: &Path) {
        std::fs::create_dir_all(dir).expect("scratch directory");
        let info = "format = \"photopose-sequence\"\nversion = 1\nwidth = 2\nheight = 1\n\
                    pixel_format = \"YUYV\"\nsource = \"test\"\n";
        std::fs::write(dir.join(INFO_FILE), info).expect("sequence.toml");
        let mut csv = format!("{}\n", CSV_HEADER);
        for (id, time) in [(5, 1_000), (9, 2_000)] {
            csv += &format!("{id},{time},{id}.yuyv,,,,,,,,,\n");
            std::fs::write(dir.join(format!("{id}.yuyv")), [id as u8; 8]).expect("frame");
        }
        std::fs::write(dir.join(FRAMES_FILE), csv).expect("frames.csv");
    }

    #[test]
    fn replay_keeps_the_recorded_frame_ids_and_a_loop_keeps_them_increasing() {
        let dir = std::env::temp_dir().join(format!("photopose-replay-ids-{}", std::process::id()));
        recording(&dir);
        let mut replay = ReplaySource::open(&dir, Some(1000.0), true).expect("replay");
        let mut buf = vec![0u8; replay.geometry().frame_len()];
        let played: Vec<(Option<u64>, u8)> = (0..5)
            .map(|_| {
                let info = replay.fill(&mut buf).expect("frame").expect("a frame");
                (info.frame_id, buf[0])
            })
            .collect();
        // Each pass adds one more than the largest recorded id (10).
        let expected = [(5, 5), (9, 9), (15, 5), (19, 9), (25, 5)].map(|(id, byte)| (Some(id), byte));
        assert_eq!(played, expected);
        std::fs::remove_dir_all(&dir).expect("clean up");
    }
}
