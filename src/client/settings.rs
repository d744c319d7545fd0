//! `[controller]`: the example visual-servo client's rate, deadline, servo gain, speed
//! limits and grasp pose, as written (serde, every field defaulted, unknown keys
//! rejected) and validated ([`ControllerSettings`]).

use std::time::Duration;

use nalgebra::Isometry3;
use serde::Deserialize;

use crate::config::{unit_pose, InvalidSetting};

/// `[controller]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct RawController {
    rate_hz: f64,
    deadline_ms: f64,
    gain: f64,
    max_speed_mm_s: f64,
    max_turn_deg_s: f64,
    grasp_position_mm: [f64; 3],
    grasp_rotation_wxyz: [f64; 4],
}

impl Default for RawController {
    fn default() -> Self {
        Self {
            rate_hz: 200.0,
            deadline_ms: 100.0,
            gain: 1.5,
            max_speed_mm_s: 150.0,
            max_turn_deg_s: 30.0,
            grasp_position_mm: [0.0, 0.0, 150.0],
            grasp_rotation_wxyz: [1.0, 0.0, 0.0, 0.0],
        }
    }
}

/// `[controller]`: the example visual-servo client (`photopose controller`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerSettings {
    /// Commands per second.
    pub rate_hz: f64,
    /// A pose whose frame was captured longer ago than this is stale.
    pub deadline: Duration,
    /// λ of the servo law, 1/s.
    pub gain: f64,
    /// Linear speed limit, mm/s.
    pub max_speed_mm_s: f64,
    /// Angular speed limit, rad/s.
    pub max_turn_rad_s: f64,
    /// The object's pose in the hand frame at which the hand may grasp it.
    pub hand_from_grasp: Isometry3<f64>,
}

impl TryFrom<RawController> for ControllerSettings {
    type Error = InvalidSetting;

    fn try_from(raw: RawController) -> Result<Self, InvalidSetting> {
        let invalid = |field, problem| InvalidSetting::new("controller", field, problem);
        for (field, v) in [
            ("rate_hz", raw.rate_hz),
            ("deadline_ms", raw.deadline_ms),
            ("gain", raw.gain),
            ("max_speed_mm_s", raw.max_speed_mm_s),
            ("max_turn_deg_s", raw.max_turn_deg_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(field, format!("{v} must be a positive number")));
            }
        }
        if raw.grasp_position_mm.iter().any(|v| !v.is_finite()) {
            return Err(invalid("grasp_position_mm", "must be finite numbers".into()));
        }
        let hand_from_grasp =
            unit_pose(raw.grasp_position_mm, raw.grasp_rotation_wxyz).map_err(|p| invalid("grasp_rotation_wxyz", p))?;
        Ok(ControllerSettings {
            rate_hz: raw.rate_hz,
            deadline: Duration::from_secs_f64(raw.deadline_ms * 1e-3),
            gain: raw.gain,
            max_speed_mm_s: raw.max_speed_mm_s,
            max_turn_rad_s: raw.max_turn_deg_s.to_radians(),
            hand_from_grasp,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_converts_to_seconds_and_radians() {
        let c = ControllerSettings::try_from(RawController::default()).unwrap();
        assert_eq!(c.deadline, Duration::from_millis(100));
        assert!((c.max_turn_rad_s - 30f64.to_radians()).abs() < 1e-15);
        assert!((c.hand_from_grasp.translation.vector.z - 150.0).abs() < 1e-12);
    }

    #[test]
    fn first_bad_field_is_named() {
        let raw = RawController {
            gain: 0.0,
            max_speed_mm_s: -1.0,
            ..RawController::default()
        };
        let e = ControllerSettings::try_from(raw).unwrap_err().to_string();
        assert_eq!(e, "[controller] gain: 0 must be a positive number");
        let raw = RawController {
            grasp_position_mm: [0.0, f64::INFINITY, 0.0],
            ..RawController::default()
        };
        let e = ControllerSettings::try_from(raw).unwrap_err().to_string();
        assert_eq!(e, "[controller] grasp_position_mm: must be finite numbers");
    }
}
