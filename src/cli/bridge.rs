//! `photopose bridge` (feature `zenoh`): publishes the poses to ROS 2 over Zenoh, as
//! `rmw_zenoh_cpp` nodes expect them (docs/ros2.md).

use anyhow::{bail, Result};

use crate::bridge::session::Network;
use crate::bridge::{self, Options};
use crate::transport::messages::POSES_SERVICE;

/// Publish each object's pose and status to ROS 2 over Zenoh.
#[derive(clap::Args, Debug)]
pub struct BridgeArgs {
    /// Zenoh endpoint to connect to, e.g. the ROS side's router `tcp/192.168.1.10:7447`
    /// (repeatable; retried until it answers, and again whenever it is lost).
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Zenoh endpoint to listen on, e.g. `tcp/0.0.0.0:7447` (repeatable; default: a
    /// free port on every interface).
    #[arg(long, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Do not look for Zenoh peers by UDP multicast (rmw_zenoh does not answer it by
    /// default: connect to its router instead).
    #[arg(long)]
    pub no_multicast: bool,
    /// ROS 2 domain id (default: `ROS_DOMAIN_ID`, else 0).
    #[arg(long, value_name = "ID")]
    pub domain: Option<u32>,
    /// `header.frame_id` of the poses.
    #[arg(long, value_name = "FRAME", default_value = "hand")]
    pub frame_id: String,
    /// Stop after this many seconds (0: run until interrupted).
    #[arg(long, default_value_t = 0.0)]
    pub seconds: f64,
    /// The iceoryx2 pose service (tests).
    #[arg(long, default_value = POSES_SERVICE, hide = true)]
    pub service: String,
}

/// `--domain`, else `ROS_DOMAIN_ID`, else 0.
fn domain(args: &BridgeArgs) -> Result<u32> {
    if let Some(d) = args.domain {
        return Ok(d);
    }
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(v) if !v.trim().is_empty() => match v.trim().parse() {
            Ok(d) => Ok(d),
            Err(_) => bail!("bad ROS_DOMAIN_ID {v:?}: a domain id 0 to {}", bridge::run::MAX_DOMAIN),
        },
        _ => Ok(0),
    }
}

/// Bridges until interrupted or `--seconds` pass, then prints one line of counts.
pub fn run(args: &BridgeArgs) -> Result<()> {
    let options = Options {
        network: Network {
            connect: args.connect.clone(),
            listen: args.listen.clone(),
            multicast: !args.no_multicast,
        },
        domain: domain(args)?,
        frame_id: args.frame_id.clone(),
        service: args.service.clone(),
        seconds: args.seconds,
    };
    let counts = bridge::run(&options)?;
    println!("bridge: {counts}");
    Ok(())
}
