//! The INI layer of the calibration file: lines, sections and `key=value` entries with
//! their line numbers, and the numbers they hold (see the parent module for why this is
//! hand-written).

use std::collections::HashMap;
use std::path::Path;

use super::{CalibrationError, Resolution};

/// A number read from the file, with where it came from.
#[derive(Debug, Clone, Copy)]
pub(super) struct Value {
    pub(super) value: f64,
    pub(super) line: usize,
}

/// One `key=value` line (key and section upper-cased).
pub(super) struct Entry<'a> {
    section: Option<String>,
    key: String,
    raw_key: &'a str,
    value: &'a str,
    line: usize,
}

pub(super) const INTRINSIC_KEYS: [&str; 9] = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];
pub(super) const STEREO_KEYS: [&str; 6] = ["BASELINE", "TY", "TZ", "CV", "RX", "RZ"];

pub(super) fn cam_section(side: &str, res: Resolution) -> String {
    format!("{side}_CAM_{}", res.name())
}

pub(super) fn is_stereo_key(key: &str) -> bool {
    if STEREO_KEYS[..3].contains(&key) {
        return true;
    }
    key.split_once('_')
        .is_some_and(|(base, suffix)| STEREO_KEYS.contains(&base) && Resolution::ALL.iter().any(|r| r.name() == suffix))
}

pub(super) fn is_known_section(name: &str) -> bool {
    name == "STEREO"
        || Resolution::ALL
            .iter()
            .any(|&r| name == cam_section("LEFT", r) || name == cam_section("RIGHT", r))
}

/// What one line of the file is.
pub(super) enum Line<'a> {
    /// Blank or only a comment.
    Blank,
    /// `[NAME]`, the name upper-cased.
    Section(String),
    /// `key=value`, both trimmed.
    Entry { key: &'a str, value: &'a str },
    /// Anything else.
    Bad,
}

impl<'a> Line<'a> {
    pub(super) fn classify(raw_line: &'a str) -> Line<'a> {
        let content = raw_line.find(['#', ';']).map_or(raw_line, |at| &raw_line[..at]).trim();
        if content.is_empty() {
            return Line::Blank;
        }
        let header = content
            .strip_prefix('[')
            .and_then(|s| s.strip_suffix(']'))
            .map(str::trim)
            .filter(|s| !s.is_empty() && !s.contains(['[', ']']));
        if let Some(name) = header {
            return Line::Section(name.to_ascii_uppercase());
        }
        match content.split_once('=') {
            Some((key, value)) if !key.trim().is_empty() && !content.starts_with('[') => Line::Entry {
                key: key.trim(),
                value: value.trim(),
            },
            _ => Line::Bad,
        }
    }
}

/// The file sorted into sections and entries.
pub(super) struct Scanned<'a> {
    /// Section names (upper-cased) in order of first appearance.
    pub(super) sections: Vec<String>,
    pub(super) entries: Vec<Entry<'a>>,
}

/// Pass 1, syntax. A file without any calibration section is reported as such rather
/// than by its first bad line: it is most likely not a calibration file at all.
pub(super) fn scan<'a>(text: &'a str, path: &Path) -> Result<Scanned<'a>, CalibrationError> {
    let mut scanned = Scanned {
        sections: Vec::new(),
        entries: Vec::new(),
    };
    let mut section: Option<String> = None;
    let mut syntax_error = None;
    for (i, raw_line) in text.lines().enumerate() {
        let line = i + 1;
        match Line::classify(raw_line) {
            Line::Blank => {}
            Line::Section(name) => {
                if !scanned.sections.contains(&name) {
                    scanned.sections.push(name.clone());
                }
                section = Some(name);
            }
            Line::Entry { key, value } => scanned.entries.push(Entry {
                section: section.clone(),
                key: key.to_ascii_uppercase(),
                raw_key: key,
                value,
                line,
            }),
            Line::Bad => {
                if syntax_error.is_none() {
                    syntax_error = Some(CalibrationError::Syntax {
                        path: path.to_path_buf(),
                        line,
                        text: raw_line.trim().chars().take(60).collect(),
                    });
                }
            }
        }
    }
    if !scanned.sections.iter().any(|s| is_known_section(s)) {
        return Err(CalibrationError::NotCalibration {
            path: path.to_path_buf(),
        });
    }
    match syntax_error {
        Some(e) => Err(e),
        None => Ok(scanned),
    }
}

/// Numbers read from the file by (section, key), both upper-cased.
pub(super) type Values = HashMap<(String, String), Value>;

/// Pass 2: the numbers of the keys photopose uses, in file order; other keys and
/// sections are not looked at. A key may appear once per section.
pub(super) fn read_values(entries: &[Entry<'_>], path: &Path) -> Result<Values, CalibrationError> {
    let mut values = Values::new();
    for e in entries {
        let Some(sec) = e.section.as_deref() else {
            continue;
        };
        let used = if sec == "STEREO" {
            is_stereo_key(&e.key)
        } else {
            is_known_section(sec) && INTRINSIC_KEYS.iter().any(|k| k.eq_ignore_ascii_case(&e.key))
        };
        if !used {
            continue;
        }
        let value = e.number(path)?;
        let slot = (sec.to_string(), e.key.clone());
        if let Some(first) = values.get(&slot) {
            return Err(CalibrationError::DuplicateKey {
                path: path.to_path_buf(),
                line: e.line,
                key: e.raw_key.to_string(),
                section: sec.to_string(),
                first_line: first.line,
            });
        }
        values.insert(slot, Value { value, line: e.line });
    }
    Ok(values)
}

impl Entry<'_> {
    /// The value as a finite number, positive for focal lengths and the baseline.
    pub(super) fn number(&self, path: &Path) -> Result<f64, CalibrationError> {
        let value: f64 = self.value.parse().map_err(|_| CalibrationError::NotANumber {
            path: path.to_path_buf(),
            line: self.line,
            key: self.raw_key.to_string(),
            value: self.value.to_string(),
        })?;
        if !value.is_finite() {
            return Err(CalibrationError::NotFinite {
                path: path.to_path_buf(),
                line: self.line,
                key: self.raw_key.to_string(),
                value: self.value.to_string(),
            });
        }
        let positive = matches!(self.key.as_str(), "FX" | "FY") || self.key.starts_with("BASELINE");
        if positive && value <= 0.0 {
            return Err(CalibrationError::NotPositive {
                path: path.to_path_buf(),
                line: self.line,
                key: self.raw_key.to_string(),
                value,
            });
        }
        Ok(value)
    }
}
