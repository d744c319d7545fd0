//! `photopose controller`: the example robot client. At `[controller] rate_hz` it takes
//! the newest pose, and either commands the end-effector velocity of the visual-servo
//! law or, when the pose is stale or not tracked, stops the arm. Commands go to a
//! [`LogDriver`]; a real robot plugs in behind [`crate::client::RobotDriver`].

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Result;

use crate::client::{Hold, LogDriver, PoseClient, RobotDriver, ServoLaw};
use crate::config::Config;

/// Servo an arm (here: log the commands) on the pose stream.
#[derive(clap::Args, Debug)]
pub struct ControllerArgs {
    /// Configuration file; built-in defaults otherwise (`[controller]`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Stop after this many seconds (0: run until interrupted).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
    /// The object to servo on, by name (default: the first of each pose set).
    #[arg(long, value_name = "NAME")]
    pub object: Option<String>,
}

/// How often a status line is printed.
const STATUS_EVERY: Duration = Duration::from_millis(500);

/// Runs the example controller until interrupted or `--seconds` pass.
pub fn run(args: &ControllerArgs) -> Result<()> {
    let config = Config::load(args.config.as_deref())?;
    let settings = config.controller;
    let mut client = PoseClient::follow("photopose-controller", args.object.as_deref(), settings.deadline)?;
    let law = ServoLaw::new(&settings);
    let mut robot = LogDriver::default();
    let period = Duration::from_secs_f64(1.0 / settings.rate_hz);
    let start = Instant::now();
    let mut status = Instant::now();
    // Why the arm is held (`None`: servoing).
    let mut holding: Option<String> = None;
    let mut held_for: Option<Option<Hold>> = None;
    println!(
        "controller: {:.0} Hz, deadline {:?}, λ = {}",
        settings.rate_hz, settings.deadline, settings.gain
    );
    while client.wait(period) {
        if args.seconds > 0.0 && start.elapsed().as_secs_f64() >= args.seconds {
            break;
        }
        client.poll()?;
        let Some(latest) = client.latest() else {
            robot.stop()?;
            if status.elapsed() >= STATUS_EVERY {
                status = Instant::now();
                println!("holding: no pose yet");
            }
            continue;
        };
        let hold = latest.hold();
        match hold {
            None => robot.command(&law.command(&latest.hand_from_object()))?,
            Some(_) => robot.stop()?,
        }
        if held_for != Some(hold) {
            held_for = Some(hold);
            holding = latest.hold_reason();
            match &holding {
                None => tracing::info!("controller: servoing from frame {}", latest.pose.frame_id),
                Some(reason) => tracing::info!("controller: holding the arm: {reason}"),
            }
        } else if hold.is_some() {
            holding = latest.hold_reason();
        }
        if status.elapsed() >= STATUS_EVERY {
            status = Instant::now();
            match &holding {
                None => {
                    let e = law.error(&latest.hand_from_object());
                    let c = robot.last;
                    println!(
                        "frame {:>6}  age {:>5.1} ms  error {:>6.1} mm {:>5.1}°  v [{:>6.1} {:>6.1} {:>6.1}] mm/s  ω [{:>5.1} {:>5.1} {:>5.1}] °/s",
                        latest.pose.frame_id,
                        latest.age.as_secs_f64() * 1e3,
                        e.translation.vector.norm(),
                        e.rotation.angle().to_degrees(),
                        c.linear_mm_s.x,
                        c.linear_mm_s.y,
                        c.linear_mm_s.z,
                        c.angular_rad_s.x.to_degrees(),
                        c.angular_rad_s.y.to_degrees(),
                        c.angular_rad_s.z.to_degrees()
                    );
                }
                Some(reason) => println!("holding: {reason}"),
            }
        }
    }
    robot.stop()?;
    println!(
        "controller: {} poses received, {} commands sent",
        client.received(),
        robot.commands
    );
    Ok(())
}
