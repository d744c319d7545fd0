//! Recorded sequences: what `photopose capture --record DIR` writes and `replay:DIR`
//! plays.
//!
//! ```text
//! DIR/sequence.toml   format = "photopose-sequence", version = 1,
//!                     width, height (per eye), pixel_format = "RGB8" | "YUYV",
//!                     source (what was recorded, informational)
//! DIR/frames.csv      one line per frame after a header line:
//!                     frame_id,capture_time_ns,file,x_mm,y_mm,z_mm,qw,qx,qy,qz,l_mm,b_mm
//!                     (the ground-truth pose and size in the hand frame; the last nine
//!                     fields are empty when the truth is unknown)
//! DIR/<file>          one side-by-side frame: `.png` (RGB8, 2·width × height) or
//!                     `.yuyv` (raw YUYV rows of 4·width bytes, as the camera sent them)
//! ```
//! Times are CLOCK_MONOTONIC nanoseconds of the recording; replay uses their
//! differences for pacing ([`due_offset`]).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::{Geometry, Truth};
use crate::camera::geometry::{is_unit_wxyz, w_nonnegative, wxyz_norm, FILE_UNIT_TOLERANCE};
use crate::config::toml_error;
use crate::vision::PixelFormat;

/// Format tag of `sequence.toml`.
pub const FORMAT: &str = "photopose-sequence";
/// Version of the sequence format this build reads and writes.
pub const VERSION: u32 = 1;
/// The sequence's description, inside a sequence directory.
pub const INFO_FILE: &str = "sequence.toml";
/// The frame list, inside a sequence directory.
pub const FRAMES_FILE: &str = "frames.csv";
/// Header line of [`FRAMES_FILE`].
pub const CSV_HEADER: &str = "frame_id,capture_time_ns,file,x_mm,y_mm,z_mm,qw,qx,qy,qz,l_mm,b_mm";

/// A sequence directory that cannot be read or written; one line naming the file.
#[derive(Debug, thiserror::Error)]
pub enum SequenceError {
    /// A file of the recording cannot be read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        reason: std::io::Error,
    },
    /// A file of the recording cannot be written.
    #[error("cannot write {path}: {reason}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        reason: std::io::Error,
    },
    /// `sequence.toml` is not a valid recording description.
    #[error("{path}: {message}")]
    Invalid {
        /// The description file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A line of `frames.csv` is malformed.
    #[error("{path}:{line}: {message}")]
    Line {
        /// The frame list.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        message: String,
    },
    /// `--record` would overwrite an existing recording.
    #[error("{path} already holds a recording; choose a new directory")]
    Exists {
        /// The recording's directory.
        path: PathBuf,
    },
}

/// `sequence.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceInfo {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`VERSION`] when written by this build.
    pub version: u32,
    /// Size of one eye, pixels.
    pub width: u32,
    /// Height of the frames, pixels.
    pub height: u32,
    /// `"RGB8"` or `"YUYV"`.
    pub pixel_format: String,
    /// What was recorded (the `--source` argument), informational.
    #[serde(default)]
    pub source: String,
}

impl SequenceInfo {
    /// The description of a recording of `geometry` frames from `source`.
    pub fn new(geometry: Geometry, source: &str) -> Self {
        Self {
            format: FORMAT.into(),
            version: VERSION,
            width: geometry.width,
            height: geometry.height,
            pixel_format: geometry.format.name().into(),
            source: source.into(),
        }
    }

    /// The frame layout, checked.
    pub fn geometry(&self, path: &Path) -> Result<Geometry, SequenceError> {
        let invalid = |message: String| SequenceError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        if self.format != FORMAT {
            return Err(invalid(format!("format is {:?}, expected {FORMAT:?}", self.format)));
        }
        if self.version != VERSION {
            return Err(invalid(format!(
                "version {} is not supported (this build reads {VERSION})",
                self.version
            )));
        }
        let format = PixelFormat::parse(&self.pixel_format).ok_or_else(|| {
            invalid(format!(
                "pixel_format {:?}: use \"RGB8\" or \"YUYV\"",
                self.pixel_format
            ))
        })?;
        if self.width == 0 || self.height == 0 || self.width > 8192 || self.height > 8192 {
            return Err(invalid(format!(
                "frame size {}x{} per eye is not usable",
                self.width, self.height
            )));
        }
        Ok(Geometry {
            width: self.width,
            height: self.height,
            format,
        })
    }
}

/// One line of `frames.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// Frame number in the recording.
    pub frame_id: u64,
    /// CLOCK_MONOTONIC when the frame was taken, ns.
    pub capture_time_ns: u64,
    /// File name inside the sequence directory.
    pub file: String,
    /// The target's true pose and size, when the source knew it.
    pub truth: Option<Truth>,
}

/// A [`FrameRecord`] as the columns of [`CSV_HEADER`] (serialised by `csv`, which quotes
/// a field when it needs to); the nine truth fields are empty when the truth is unknown.
#[derive(Serialize)]
struct FrameRow<'a> {
    frame_id: u64,
    capture_time_ns: u64,
    file: &'a str,
    x_mm: Option<f64>,
    y_mm: Option<f64>,
    z_mm: Option<f64>,
    qw: Option<f64>,
    qx: Option<f64>,
    qy: Option<f64>,
    qz: Option<f64>,
    l_mm: Option<f64>,
    b_mm: Option<f64>,
}

impl FrameRecord {
    /// The row written for this record: the quaternion with `w ≥ 0`.
    fn row(&self) -> FrameRow<'_> {
        let mut row = FrameRow {
            frame_id: self.frame_id,
            capture_time_ns: self.capture_time_ns,
            file: &self.file,
            x_mm: None,
            y_mm: None,
            z_mm: None,
            qw: None,
            qx: None,
            qy: None,
            qz: None,
            l_mm: None,
            b_mm: None,
        };
        if let Some(t) = &self.truth {
            let p = t.hand_from_model.translation.vector;
            let q = t.hand_from_model.rotation.into_inner();
            [row.x_mm, row.y_mm, row.z_mm] = [Some(p.x), Some(p.y), Some(p.z)];
            [row.qw, row.qx, row.qy, row.qz] = w_nonnegative([q.w, q.i, q.j, q.k]).map(Some);
            [row.l_mm, row.b_mm] = t.size_mm.map(Some);
        }
        row
    }

    /// The CSV line (no newline), as [`FramesCsv`] writes it.
    pub fn to_csv(&self) -> String {
        let mut out = FramesCsv {
            csv: csv::WriterBuilder::new().has_headers(false).from_writer(Vec::new()),
        };
        // Writing into a Vec cannot fail.
        let bytes = out.write(self).ok().and_then(|()| out.csv.into_inner().ok());
        String::from_utf8(bytes.unwrap_or_default())
            .unwrap_or_default()
            .trim_end()
            .to_string()
    }

    /// Parses one CSV line; the message says what is wrong.
    pub fn parse(line: &str) -> Result<Self, String> {
        let mut reader = csv_reader(line.as_bytes());
        match reader.records().next() {
            Some(Ok(record)) => Self::from_fields(&record),
            Some(Err(e)) => Err(e.to_string()),
            None => Err("expected 12 comma-separated fields, found 0".into()),
        }
    }

    /// Checks and converts the (trimmed) fields of one line.
    fn from_fields(fields: &csv::StringRecord) -> Result<Self, String> {
        if fields.len() != 12 {
            return Err(format!("expected 12 comma-separated fields, found {}", fields.len()));
        }
        let int = |i: usize, name: &str| {
            fields[i]
                .parse::<u64>()
                .map_err(|_| format!("{name} {:?} is not a non-negative integer", &fields[i]))
        };
        let (frame_id, capture_time_ns) = (int(0, "frame_id")?, int(1, "capture_time_ns")?);
        let file = &fields[2];
        if file.is_empty() || file.contains('/') || file.contains('\\') || file.starts_with('.') {
            return Err(format!(
                "file {file:?} must be a plain file name in the sequence directory"
            ));
        }
        let truth = if fields.iter().skip(3).all(str::is_empty) {
            None
        } else {
            Some(truth_from_fields(fields)?)
        };
        Ok(Self {
            frame_id,
            capture_time_ns,
            file: file.to_string(),
            truth,
        })
    }
}

/// The truth in fields 4 to 12 of a line: position, unit quaternion, positive size.
fn truth_from_fields(fields: &csv::StringRecord) -> Result<Truth, String> {
    let mut v = [0.0; 9];
    for (k, x) in v.iter_mut().enumerate() {
        *x = fields[3 + k]
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("truth field {} {:?} is not a finite number", 4 + k, &fields[3 + k]))?;
    }
    let wxyz = [v[3], v[4], v[5], v[6]];
    if !is_unit_wxyz(wxyz, FILE_UNIT_TOLERANCE) {
        return Err(format!("truth quaternion has norm {:.4}, not 1", wxyz_norm(wxyz)));
    }
    let q = Quaternion::new(v[3], v[4], v[5], v[6]);
    if v[7] <= 0.0 || v[8] <= 0.0 {
        return Err("truth size must be positive".into());
    }
    Ok(Truth {
        hand_from_model: Isometry3::from_parts(
            Translation3::from(Vector3::new(v[0], v[1], v[2])),
            UnitQuaternion::from_quaternion(q),
        ),
        size_mm: [v[7], v[8]],
    })
}

/// A reader of `frames.csv` text: no header handling (the caller checks the first
/// line), any number of fields per line (checked per line), fields trimmed.
fn csv_reader(text: &[u8]) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text)
}

/// Writes `frames.csv`: the header line, then one line per [`FrameRecord`], each
/// flushed, so a recording cut short still reads back.
pub struct FramesCsv<W: Write> {
    csv: csv::Writer<W>,
}

impl<W: Write> FramesCsv<W> {
    /// Starts the file with [`CSV_HEADER`].
    pub fn new(out: W) -> std::io::Result<Self> {
        let mut csv = csv::WriterBuilder::new().has_headers(false).from_writer(out);
        csv.write_record(CSV_HEADER.split(','))?;
        csv.flush()?;
        Ok(Self { csv })
    }

    /// Appends the line of `rec` and flushes it.
    pub fn write(&mut self, rec: &FrameRecord) -> std::io::Result<()> {
        self.csv.serialize(rec.row())?;
        self.csv.flush()
    }
}

/// A sequence directory's description and frame list.
#[derive(Debug, Clone)]
pub struct Sequence {
    /// The sequence directory.
    pub dir: PathBuf,
    /// Its `sequence.toml`.
    pub info: SequenceInfo,
    /// The frame layout, checked.
    pub geometry: Geometry,
    /// The lines of `frames.csv`, capture times not decreasing.
    pub frames: Vec<FrameRecord>,
}

impl Sequence {
    /// Reads and checks `DIR/sequence.toml` and `DIR/frames.csv` (not the frames).
    pub fn open(dir: &Path) -> Result<Self, SequenceError> {
        let info_path = dir.join(INFO_FILE);
        let text = std::fs::read_to_string(&info_path).map_err(|reason| SequenceError::Read {
            path: info_path.clone(),
            reason,
        })?;
        let info: SequenceInfo = toml::from_str(&text).map_err(|e| SequenceError::Invalid {
            path: info_path.clone(),
            message: toml_error(&text, &e).one_line_with_line_number(),
        })?;
        let geometry = info.geometry(&info_path)?;
        let csv_path = dir.join(FRAMES_FILE);
        let text = std::fs::read_to_string(&csv_path).map_err(|reason| SequenceError::Read {
            path: csv_path.clone(),
            reason,
        })?;
        let line_error = |line: u64, message: String| SequenceError::Line {
            path: csv_path.clone(),
            line: line as usize,
            message,
        };
        let mut records = csv_reader(text.as_bytes()).into_records();
        match records.next() {
            Some(Ok(h)) if h.iter().eq(CSV_HEADER.split(',')) => {}
            _ => return Err(line_error(1, format!("the first line must be the header {CSV_HEADER}"))),
        }
        let mut frames: Vec<FrameRecord> = Vec::new();
        for record in records {
            let record = record.map_err(|e| {
                let line = e.position().map_or(0, csv::Position::line);
                line_error(line, e.to_string())
            })?;
            if record.len() == 1 && record[0].is_empty() {
                continue; // a blank line
            }
            let line = record.position().map_or(0, csv::Position::line);
            let rec = FrameRecord::from_fields(&record).map_err(|m| line_error(line, m))?;
            if let Some(prev) = frames.last() {
                if rec.capture_time_ns < prev.capture_time_ns {
                    return Err(line_error(line, "capture times must not decrease".into()));
                }
            }
            frames.push(rec);
        }
        if frames.is_empty() {
            return Err(line_error(1, "the sequence has no frames".into()));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            info,
            geometry,
            frames,
        })
    }

    /// Recorded capture times, ns.
    pub fn times(&self) -> Vec<u64> {
        self.frames.iter().map(|f| f.capture_time_ns).collect()
    }
}

/// When frame `n` of playback is due, after the start of playback: at `fps` when given,
/// else at the recorded pace. Past the last frame playback loops: each pass lasts the
/// recording's span plus one mean frame period.
pub fn due_offset(times: &[u64], n: u64, fps: Option<f64>) -> Duration {
    if let Some(fps) = fps.filter(|f| f.is_finite() && *f > 0.0) {
        return Duration::from_secs_f64(n as f64 / fps);
    }
    let (Some(&first), Some(&last)) = (times.first(), times.last()) else {
        return Duration::ZERO;
    };
    let len = times.len() as u64;
    let span = last.saturating_sub(first);
    let period = if len > 1 { span / (len - 1) } else { 0 };
    let (pass, i) = (n / len, (n % len) as usize);
    Duration::from_nanos(pass * (span + period) + (times[i] - first))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_through_csv() {
        let truth = Truth {
            hand_from_model: Isometry3::from_parts(
                Translation3::new(40.0, -20.0, 650.0),
                UnitQuaternion::from_euler_angles(0.5, 0.1, -0.2),
            ),
            size_mm: [180.0, 159.0],
        };
        for (truth, file) in [(Some(truth), "000007.png"), (None, "a, \"b\".png")] {
            let rec = FrameRecord {
                frame_id: 7,
                capture_time_ns: 123_456_789,
                file: file.into(),
                truth,
            };
            let back = FrameRecord::parse(&rec.to_csv()).unwrap();
            assert_eq!(
                (back.frame_id, back.capture_time_ns, &back.file),
                (7, 123_456_789, &rec.file)
            );
            match (back.truth, truth) {
                (Some(a), Some(b)) => {
                    assert!(
                        (a.hand_from_model.translation.vector - b.hand_from_model.translation.vector).norm() < 1e-9
                    );
                    assert!(a.hand_from_model.rotation.angle_to(&b.hand_from_model.rotation) < 1e-9);
                    assert_eq!(a.size_mm, b.size_mm);
                }
                (None, None) => {}
                other => panic!("truth changed: {other:?}"),
            }
        }
    }

    #[test]
    fn bad_lines_say_what_is_wrong() {
        for (line, needle) in [
            ("1,2,a.png", "12 comma-separated"),
            ("x,2,a.png,,,,,,,,,", "frame_id"),
            ("1,-2,a.png,,,,,,,,,", "capture_time_ns"),
            ("1,2,../a.png,,,,,,,,,", "plain file name"),
            ("1,2,a.png,1,2,3,1,0,0,0,10,nan", "finite"),
            ("1,2,a.png,1,2,3,2,0,0,0,10,10", "norm"),
            ("1,2,a.png,1,2,3,1,0,0,0,0,10", "positive"),
        ] {
            let e = FrameRecord::parse(line).unwrap_err();
            assert!(e.contains(needle), "{line}: {e}");
        }
    }

    #[test]
    fn pacing_follows_the_recording_or_a_fixed_rate_and_loops() {
        let times = [1_000, 21_000, 41_000];
        let d = |n| due_offset(&times, n, None).as_nanos();
        assert_eq!([d(0), d(1), d(2)], [0, 20_000, 40_000]);
        // The second pass starts one mean period after the last frame.
        assert_eq!([d(3), d(4), d(5)], [60_000, 80_000, 100_000]);
        assert_eq!(due_offset(&times, 4, Some(100.0)), Duration::from_millis(40));
        assert_eq!(due_offset(&[5], 3, None), Duration::ZERO);
        assert_eq!(due_offset(&[], 3, None), Duration::ZERO);
    }

    #[test]
    fn sequence_files_are_checked() {
        let dir = std::env::temp_dir().join(format!("photopose-seq-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("sequence.toml"), "{e}");
        let info = SequenceInfo::new(
            Geometry {
                width: 4,
                height: 2,
                format: PixelFormat::Yuyv,
            },
            "test",
        );
        std::fs::write(dir.join(INFO_FILE), toml::to_string(&info).unwrap()).unwrap();
        std::fs::write(dir.join(FRAMES_FILE), "frame,time\n").unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("frames.csv:1") && e.contains("header"), "{e}");
        std::fs::write(
            dir.join(FRAMES_FILE),
            format!("{CSV_HEADER}\n0,100,a.yuyv,,,,,,,,,\n1,50,b.yuyv,,,,,,,,,\n"),
        )
        .unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("frames.csv:3") && e.contains("decrease"), "{e}");
        let mut written = Vec::new();
        let mut csv = FramesCsv::new(&mut written).unwrap();
        for (frame_id, file) in [(0, "a.yuyv"), (1, "b, c.yuyv")] {
            let rec = FrameRecord {
                frame_id,
                capture_time_ns: 100,
                file: file.into(),
                truth: None,
            };
            csv.write(&rec).unwrap();
        }
        drop(csv);
        let text = String::from_utf8(written).unwrap();
        assert_eq!(
            text,
            format!("{CSV_HEADER}\n0,100,a.yuyv,,,,,,,,,\n1,100,\"b, c.yuyv\",,,,,,,,,\n")
        );
        std::fs::write(dir.join(FRAMES_FILE), format!("{text}\n  \n")).unwrap();
        let seq = Sequence::open(&dir).unwrap();
        assert_eq!(seq.frames[1].file, "b, c.yuyv");
        assert_eq!(seq.geometry.frame_len(), 2 * 4 * 2 * 2);
        std::fs::write(
            dir.join(INFO_FILE),
            "format = \"photopose-sequence\"\nversion = 9\nwidth = 4\nheight = 2\npixel_format = \"RGB8\"\n",
        )
        .unwrap();
        let e = Sequence::open(&dir).unwrap_err().to_string();
        assert!(e.contains("sequence.toml") && e.contains("version 9"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
