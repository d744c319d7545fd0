//! `photopose capture --record DIR`: writes the published frames as a [`sequence`]
//! (RGB8 frames as PNG, YUYV frames raw, as the camera sent them) on a writer thread.
//! The camera never waits for the disk: each frame is copied into one of a few
//! recycled buffers, and when none is free the frame is left out of the recording and
//! counted.
//!
//! [`sequence`]: super::sequence

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use crossbeam::channel::{bounded, Receiver, Sender};
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};

use super::sequence::{FrameRecord, FramesCsv, SequenceError, SequenceInfo, FRAMES_FILE, INFO_FILE};
use super::{FrameInfo, Geometry};
use crate::vision::PixelFormat;

/// Frames waiting for the writer at most.
const QUEUE: usize = 8;

/// One frame handed to the writer.
struct Job {
    frame_id: u64,
    info: FrameInfo,
    bytes: Vec<u8>,
}

/// Records frames into a sequence directory.
pub struct Recorder {
    dir: PathBuf,
    jobs: Option<Sender<Job>>,
    free: Receiver<Vec<u8>>,
    writer: Option<JoinHandle<Result<u64, SequenceError>>>,
    /// Frames left out because the writer was behind.
    pub skipped: u64,
}

impl Recorder {
    /// Starts a recording of `geometry` frames into `dir` (created if missing; refused
    /// if it already holds a recording).
    pub fn create(dir: &Path, geometry: Geometry, source: &str) -> Result<Self, SequenceError> {
        let info_path = dir.join(INFO_FILE);
        if info_path.exists() {
            return Err(SequenceError::Exists {
                path: dir.to_path_buf(),
            });
        }
        let write_error = |path: &Path| {
            let path = path.to_path_buf();
            move |reason| SequenceError::Write { path, reason }
        };
        std::fs::create_dir_all(dir).map_err(write_error(dir))?;
        let info = SequenceInfo::new(geometry, source);
        let text = toml::to_string(&info).map_err(|e| SequenceError::Invalid {
            path: info_path.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(&info_path, text).map_err(write_error(&info_path))?;
        let csv_path = dir.join(FRAMES_FILE);
        let file = File::create(&csv_path).map_err(write_error(&csv_path))?;
        let mut csv = FramesCsv::new(file).map_err(write_error(&csv_path))?;

        let (give_back, free) = bounded(QUEUE);
        for _ in 0..QUEUE {
            // Cannot fail: the channel has room for every buffer.
            let _ = give_back.send(vec![0u8; geometry.frame_len()]);
        }
        let (jobs, queue) = bounded::<Job>(QUEUE);
        let out = dir.to_path_buf();
        let writer = std::thread::Builder::new()
            .name("photopose-record".into())
            .spawn(move || {
                let mut written = 0;
                for job in queue {
                    let file = format!("{:06}.{}", job.frame_id, extension(geometry.format));
                    write_frame(&out.join(&file), geometry, &job.bytes)?;
                    let rec = FrameRecord {
                        frame_id: job.frame_id,
                        capture_time_ns: job.info.capture_time_ns,
                        file,
                        truth: job.info.truth[0],
                    };
                    csv.write(&rec).map_err(write_error(&csv_path))?;
                    written += 1;
                    // The recorder may be gone already; the buffer is then not needed.
                    let _ = give_back.send(job.bytes);
                }
                Ok(written)
            })
            .map_err(write_error(dir))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            jobs: Some(jobs),
            free,
            writer: Some(writer),
            skipped: 0,
        })
    }

    /// Queues a copy of frame `frame_id` for writing, or counts it as skipped when the
    /// writer is behind. Fails once the writer has failed (disk full, …).
    pub fn record(&mut self, frame_id: u64, info: &FrameInfo, frame: &[u8]) -> Result<(), SequenceError> {
        self.queue(frame_id, info, frame, false)
    }

    /// [`Recorder::record`] that waits for the writer instead of leaving the frame out
    /// (a recording made offline, such as a rendered scenario).
    pub fn record_all(&mut self, frame_id: u64, info: &FrameInfo, frame: &[u8]) -> Result<(), SequenceError> {
        self.queue(frame_id, info, frame, true)
    }

    fn queue(&mut self, frame_id: u64, info: &FrameInfo, frame: &[u8], wait: bool) -> Result<(), SequenceError> {
        if self.writer.as_ref().is_some_and(JoinHandle::is_finished) {
            self.finish_writer()?;
        }
        let free = if wait {
            self.free.recv().ok()
        } else {
            self.free.try_recv().ok()
        };
        let (Some(jobs), Some(mut bytes)) = (&self.jobs, free) else {
            self.skipped += 1;
            return Ok(());
        };
        if bytes.len() != frame.len() {
            bytes.resize(frame.len(), 0);
        }
        bytes.copy_from_slice(frame);
        let job = Job {
            frame_id,
            info: *info,
            bytes,
        };
        if jobs.send(job).is_err() {
            self.finish_writer()?;
        }
        Ok(())
    }

    /// Writes what is queued and closes the recording: the frames written.
    pub fn finish(mut self) -> Result<u64, SequenceError> {
        self.finish_writer()
    }

    fn finish_writer(&mut self) -> Result<u64, SequenceError> {
        self.jobs = None;
        match self.writer.take() {
            Some(w) => w.join().unwrap_or_else(|_| {
                Err(SequenceError::Invalid {
                    path: self.dir.clone(),
                    message: "the recording thread failed".into(),
                })
            }),
            None => Ok(0),
        }
    }
}

/// File extension of a frame of `format`.
fn extension(format: PixelFormat) -> &'static str {
    match format {
        PixelFormat::Rgb8 => "png",
        PixelFormat::Yuyv => "yuyv",
    }
}

/// Writes one frame file: PNG (fast compression) for RGB8, the raw bytes for YUYV.
fn write_frame(path: &Path, geometry: Geometry, bytes: &[u8]) -> Result<(), SequenceError> {
    let io = |reason| SequenceError::Write {
        path: path.to_path_buf(),
        reason,
    };
    let mut out = BufWriter::new(File::create(path).map_err(io)?);
    match geometry.format {
        PixelFormat::Rgb8 => PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
            .write_image(bytes, 2 * geometry.width, geometry.height, ExtendedColorType::Rgb8)
            .map_err(|e| io(std::io::Error::other(e.to_string())))?,
        PixelFormat::Yuyv => out.write_all(bytes).map_err(io)?,
    }
    out.flush().map_err(io)
}
