//! What robot code uses to consume photopose: the newest pose of `photopose/poses` with
//! its age, a deadline that flags a stale pose (estimator gone, camera stalled, object
//! lost), and a position-based visual-servo law that turns the error between the
//! object's pose and a desired grasp pose into an end-effector velocity command for a
//! [`RobotDriver`].
//!
//! ```no_run
//! use photopose::client::{LogDriver, PoseClient, RobotDriver, ServoLaw};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let config = photopose::config::Config::load(None)?;
//! let mut client = PoseClient::connect("my-robot", config.controller.deadline)?;
//! let law = ServoLaw::new(&config.controller);
//! let mut robot = LogDriver::default();
//! while client.wait(std::time::Duration::from_millis(5)) {
//!     client.poll()?;
//!     match client.latest() {
//!         Some(p) if p.usable() => robot.command(&law.command(&p.hand_from_object()))?,
//!         _ => robot.stop()?,
//!     }
//! }
//! robot.stop()?;
//! # Ok(())
//! # }
//! ```

pub mod settings;

use std::time::Duration;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::client::settings::ControllerSettings;
use crate::transport::ipc::{receive_poses, Ipc, IpcError, PoseSubscriber};
use crate::transport::messages::{monotonic_ns, PoseMsg, Status, POSES_SERVICE};

/// A problem of the client side.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The pose service could not be opened or read.
    #[error("iceoryx2: {0}")]
    Transport(#[from] IpcError),
    /// The robot driver refused a command.
    #[error("robot driver: {0}")]
    Driver(String),
}

/// Subscribes to `photopose/poses` and keeps the newest pose of one object.
pub struct PoseClient {
    ipc: Ipc,
    poses: PoseSubscriber,
    deadline: Duration,
    object: Option<String>,
    newest: Option<PoseMsg>,
    received: u64,
}

impl PoseClient {
    /// Connects as iceoryx2 node `name` and follows the first object of each pose set
    /// (the only one of a single-model estimator); poses older than `deadline` are stale.
    pub fn connect(name: &str, deadline: Duration) -> Result<Self, ClientError> {
        Self::follow(name, None, deadline)
    }

    /// [`PoseClient::connect`], following the object named `object` (`None`: the first).
    pub fn follow(name: &str, object: Option<&str>, deadline: Duration) -> Result<Self, ClientError> {
        let ipc = Ipc::new(name)?;
        let poses = ipc.pose_subscriber(POSES_SERVICE)?;
        Ok(Self {
            ipc,
            poses,
            deadline,
            object: object.map(str::to_string),
            newest: None,
            received: 0,
        })
    }

    /// Takes every pose set that arrived since the last call and keeps the followed
    /// object's newest pose; returns how many of its poses arrived.
    pub fn poll(&mut self) -> Result<usize, ClientError> {
        let mut n = 0;
        while let Some(set) = receive_poses(&self.poses)? {
            let found = match &self.object {
                Some(name) => set.get(name),
                None => set.first(),
            };
            let Some(&pose) = found else { continue };
            // A restarted estimator starts its frame ids again: newest by capture time.
            if self.newest.is_none_or(|p| pose.capture_time_ns >= p.capture_time_ns) {
                self.newest = Some(pose);
            }
            n += 1;
        }
        self.received += n as u64;
        Ok(n)
    }

    /// Sleeps up to `timeout`; false once the process was asked to terminate (Ctrl-C,
    /// SIGTERM): the robot loop's pacing.
    pub fn wait(&self, timeout: Duration) -> bool {
        self.ipc.wait(timeout)
    }

    /// Poses received so far.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// The newest pose judged now.
    pub fn latest(&self) -> Option<Latest> {
        self.newest.map(|p| Latest::judge(p, monotonic_ns(), self.deadline))
    }
}

/// A pose with its age, judged against a deadline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latest {
    /// The pose as received.
    pub pose: PoseMsg,
    /// Time since its frame was captured.
    pub age: Duration,
    /// Older than the deadline: the estimator or the camera has stopped.
    pub stale: bool,
}

impl Latest {
    /// Judges `pose` at CLOCK_MONOTONIC time `now_ns`.
    pub fn judge(pose: PoseMsg, now_ns: u64, deadline: Duration) -> Self {
        let age = Duration::from_nanos(now_ns.saturating_sub(pose.capture_time_ns));
        Self {
            pose,
            age,
            stale: age > deadline,
        }
    }

    /// Fresh and tracked: safe to servo on.
    pub fn usable(&self) -> bool {
        self.hold().is_none()
    }

    /// Why the pose must not be acted on, if it must not.
    pub fn hold(&self) -> Option<Hold> {
        if !self.pose.is_sound() {
            Some(Hold::Unsound)
        } else if self.stale {
            Some(Hold::Stale)
        } else {
            match self.pose.status() {
                Ok(Status::Tracking) => None,
                Ok(other) => Some(Hold::NotTracking(other)),
                Err(_) => Some(Hold::Unsound),
            }
        }
    }

    /// [`Latest::hold`] in words.
    pub fn hold_reason(&self) -> Option<String> {
        self.hold().map(|h| match h {
            Hold::Unsound => "unsound pose (NaN, infinity, unknown status or non-unit quaternion)".into(),
            Hold::Stale => format!("stale pose: frame {} is {:.0} ms old", self.pose.frame_id, ms(self.age)),
            Hold::NotTracking(s) => format!("estimator status {}", s.name()),
        })
    }

    /// `H_T_O`: the object (model) pose in the hand frame.
    pub fn hand_from_object(&self) -> Isometry3<f64> {
        let [w, x, y, z] = self.pose.orientation_wxyz;
        let [px, py, pz] = self.pose.position_mm;
        Isometry3::from_parts(
            Translation3::new(px, py, pz),
            UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        )
    }
}

/// Why a pose must not be acted on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hold {
    /// A number is NaN or infinite, the status unknown or the quaternion not unit: a
    /// broken or foreign publisher.
    Unsound,
    /// Older than the deadline: the estimator or the camera has stopped.
    Stale,
    /// The estimator is searching for or has lost the object.
    NotTracking(Status),
}

/// `"tracking"`, `"searching"`, `"lost"` or `"unknown (N)"` for a status code.
pub fn status_name(code: u32) -> String {
    Status::try_from(code).map_or_else(|e| format!("unknown ({})", e.0), |s| s.name().into())
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// An end-effector velocity in the hand frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VelocityCommand {
    /// Linear velocity of the hand, mm/s, hand frame.
    pub linear_mm_s: Vector3<f64>,
    /// Angular velocity of the hand (axis times rate), rad/s, hand frame.
    pub angular_rad_s: Vector3<f64>,
}

/// Position-based visual servoing: the hand moves so that the object's pose in the hand
/// frame approaches the grasp pose `H*_T_O`. With the current pose `H_T_O`, the desired
/// hand pose seen from the current hand is `H_T_H* = H_T_O · (H*_T_O)⁻¹`, with
/// translation `t` and rotation `θu`; the command is `v = λ·t`, `ω = λ·θu`, each scaled
/// down to its speed limit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoLaw {
    /// λ, 1/s: the command is this times the pose error.
    pub gain: f64,
    /// Linear speed limit, mm/s.
    pub max_speed_mm_s: f64,
    /// Angular speed limit, rad/s.
    pub max_turn_rad_s: f64,
    /// `H*_T_O`: the object's pose in the hand frame at which the hand may grasp it (mm).
    pub hand_from_grasp: Isometry3<f64>,
}

impl ServoLaw {
    /// The law of the `[controller]` settings.
    pub fn new(settings: &ControllerSettings) -> Self {
        Self {
            gain: settings.gain,
            max_speed_mm_s: settings.max_speed_mm_s,
            max_turn_rad_s: settings.max_turn_rad_s,
            hand_from_grasp: settings.hand_from_grasp,
        }
    }

    /// `H_T_H*`: where the hand should be, in the current hand frame.
    pub fn error(&self, hand_from_object: &Isometry3<f64>) -> Isometry3<f64> {
        hand_from_object * self.hand_from_grasp.inverse()
    }

    /// The velocity command for the object at `hand_from_object`.
    pub fn command(&self, hand_from_object: &Isometry3<f64>) -> VelocityCommand {
        let e = self.error(hand_from_object);
        let limit = |v: Vector3<f64>, max: f64| {
            let n = v.norm();
            if n > max {
                v * (max / n)
            } else {
                v
            }
        };
        VelocityCommand {
            linear_mm_s: limit(e.translation.vector * self.gain, self.max_speed_mm_s),
            angular_rad_s: limit(e.rotation.scaled_axis() * self.gain, self.max_turn_rad_s),
        }
    }
}

/// Where velocity commands go: implement it for your robot's interface.
pub trait RobotDriver {
    /// Sends one end-effector velocity (hand frame).
    fn command(&mut self, cmd: &VelocityCommand) -> Result<(), ClientError>;

    /// Brings the arm to rest (no usable pose, or shutting down).
    fn stop(&mut self) -> Result<(), ClientError> {
        self.command(&VelocityCommand::default())
    }
}

/// A driver that only logs the commands it gets (at debug level) and keeps the last.
#[derive(Debug, Default)]
pub struct LogDriver {
    /// The last command received (zero before the first).
    pub last: VelocityCommand,
    /// Commands received so far, stops included.
    pub commands: u64,
}

impl RobotDriver for LogDriver {
    fn command(&mut self, cmd: &VelocityCommand) -> Result<(), ClientError> {
        tracing::debug!(
            "command v [{:.1} {:.1} {:.1}] mm/s ω [{:.3} {:.3} {:.3}] rad/s",
            cmd.linear_mm_s.x,
            cmd.linear_mm_s.y,
            cmd.linear_mm_s.z,
            cmd.angular_rad_s.x,
            cmd.angular_rad_s.y,
            cmd.angular_rad_s.z
        );
        self.last = *cmd;
        self.commands += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> ServoLaw {
        ServoLaw {
            gain: 2.0,
            max_speed_mm_s: 100.0,
            max_turn_rad_s: 0.5,
            hand_from_grasp: Isometry3::translation(0.0, 0.0, 150.0),
        }
    }

    fn pose(frame_id: u64, capture_time_ns: u64, status: u32) -> PoseMsg {
        PoseMsg {
            frame_id,
            capture_time_ns,
            orientation_wxyz: [1.0, 0.0, 0.0, 0.0],
            status,
            ..Default::default()
        }
    }

    #[test]
    fn at_the_grasp_pose_the_command_is_zero() {
        let c = law().command(&Isometry3::translation(0.0, 0.0, 150.0));
        assert!(c.linear_mm_s.norm() < 1e-12 && c.angular_rad_s.norm() < 1e-12);
    }

    #[test]
    fn the_hand_moves_towards_the_object_within_limits() {
        // Object 20 mm further and 10 mm to the right than at the grasp: move forward and
        // right at λ·error.
        let c = law().command(&Isometry3::translation(10.0, 0.0, 170.0));
        assert!((c.linear_mm_s - Vector3::new(20.0, 0.0, 40.0)).norm() < 1e-9, "{c:?}");
        // Far away: the speed is capped, the direction kept.
        let c = law().command(&Isometry3::translation(0.0, 0.0, 1150.0));
        assert!((c.linear_mm_s - Vector3::new(0.0, 0.0, 100.0)).norm() < 1e-9, "{c:?}");
    }

    #[test]
    fn the_hand_turns_the_way_the_object_is_turned() {
        // The object turned +0.1 rad about the hand's z axis: the hand turns +z.
        let turned = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 150.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1),
        );
        let c = law().command(&turned);
        assert!((c.angular_rad_s - Vector3::new(0.0, 0.0, 0.2)).norm() < 1e-9, "{c:?}");
        // After the hand turns by the error, the object is at the grasp pose.
        let e = law().error(&turned);
        let after = e.inverse() * turned;
        assert!((after.translation.vector - Vector3::new(0.0, 0.0, 150.0)).norm() < 1e-9);
        assert!(after.rotation.angle() < 1e-9);
        // A big turn is capped at the limit.
        let big = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 150.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.0),
        );
        assert!((law().command(&big).angular_rad_s.norm() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn old_or_untracked_poses_are_not_usable() {
        let deadline = Duration::from_millis(100);
        let fresh = Latest::judge(pose(3, 1_000_000_000, Status::Tracking as u32), 1_050_000_000, deadline);
        assert!(fresh.usable() && fresh.hold_reason().is_none());
        assert_eq!(fresh.age, Duration::from_millis(50));
        let old = Latest::judge(pose(3, 1_000_000_000, Status::Tracking as u32), 1_150_000_000, deadline);
        assert!(old.stale && !old.usable());
        let reason = old.hold_reason().unwrap();
        assert!(reason.contains("stale") && reason.contains("150 ms"), "{reason}");
        let lost = Latest::judge(pose(3, 1_000_000_000, Status::Lost as u32), 1_010_000_000, deadline);
        assert!(!lost.usable());
        assert_eq!(lost.hold_reason().unwrap(), "estimator status lost");
        // A fresh, tracking pose with a NaN is never acted on.
        let mut broken = pose(4, 1_000_000_000, Status::Tracking as u32);
        broken.position_mm[2] = f64::NAN;
        let broken = Latest::judge(broken, 1_010_000_000, deadline);
        assert_eq!(broken.hold(), Some(Hold::Unsound));
        // A clock that appears to run backwards gives age 0, not a panic.
        assert_eq!(
            Latest::judge(pose(1, 5, Status::Tracking as u32), 1, deadline).age,
            Duration::ZERO
        );
    }

    #[test]
    fn the_driver_trait_stops_with_a_zero_command() {
        let mut d = LogDriver {
            last: VelocityCommand {
                linear_mm_s: Vector3::x(),
                angular_rad_s: Vector3::y(),
            },
            commands: 0,
        };
        d.stop().unwrap();
        assert_eq!((d.last, d.commands), (VelocityCommand::default(), 1));
    }
}
