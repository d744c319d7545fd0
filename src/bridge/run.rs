//! The bridge loop: pose sets from iceoryx2 in, ROS 2 messages on Zenoh out.
//!
//! The bridge is a subscriber like any other: iceoryx2 keeps a bounded buffer per
//! subscriber and overwrites its oldest sample, so a slow bridge never blocks the
//! estimator. When sets pile up anyway, the bridge keeps the newest few and skips the rest.

use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use zenoh::liveliness::LivelinessToken;
use zenoh::{Session, Wait};

use super::clock::RealtimeMap;
use super::msgs::{diagnostic_status, pose_stamped, Stamp};
use super::names::Node;
use super::session::Network;
use super::topics::ObjectTopics;
use crate::transport::ipc::{receive_poses, Ipc, PoseSubscriber};
use crate::transport::messages::{PoseMsg, PoseSet};

/// The ROS 2 node name of the bridge.
pub const NODE_NAME: &str = "photopose_bridge";
/// The largest ROS 2 domain id (REP 2000's DDS port mapping; rmw_zenoh follows it).
pub const MAX_DOMAIN: u32 = 232;
/// Objects the bridge publishes at most (each has two publishers).
pub const MAX_TOPIC_OBJECTS: usize = 64;
/// Sets held for publishing; older ones are skipped when more are waiting.
const BACKLOG: usize = 4;
/// How often the counts are logged.
const LOG_EVERY: Duration = Duration::from_secs(2);

/// What the bridge reads and where it publishes.
#[derive(Debug, Clone)]
pub struct Options {
    /// The Zenoh side.
    pub network: Network,
    /// `ROS_DOMAIN_ID`, 0..=232.
    pub domain: u32,
    /// `header.frame_id` of the poses (the hand frame).
    pub frame_id: String,
    /// The iceoryx2 pose service.
    pub service: String,
    /// Stop after this many seconds (0: run until interrupted).
    pub seconds: f64,
}

/// Checks a `header.frame_id`: 1–255 printable ASCII characters without spaces, not
/// starting with `/` (tf2 rejects a leading slash).
pub fn check_frame_id(id: &str) -> Result<()> {
    if id.is_empty() || id.len() > 255 || !id.bytes().all(|b| b.is_ascii_graphic()) || id.starts_with('/') {
        bail!("bad frame id {id:?}: 1 to 255 printable ASCII characters without spaces, not starting with /");
    }
    Ok(())
}

impl Options {
    /// Checks every option before anything is opened.
    pub fn check(&self) -> Result<()> {
        check_frame_id(&self.frame_id)?;
        if self.domain > MAX_DOMAIN {
            bail!("bad domain id {}: ROS 2 domain ids are 0 to {MAX_DOMAIN}", self.domain);
        }
        if !(self.seconds.is_finite() && self.seconds >= 0.0) {
            bail!("bad --seconds {}: a duration of 0 s or more", self.seconds);
        }
        self.network.check()
    }
}

/// What the bridge did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Poses (objects of pose sets) received over iceoryx2.
    pub poses_in: u64,
    /// Poses published on Zenoh (their pose and status messages both handed to Zenoh).
    pub published: u64,
    /// Poses skipped because newer sets were waiting, or because a put failed.
    pub dropped: u64,
    /// Objects with topics.
    pub objects: usize,
}

impl std::fmt::Display for Counts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} poses in, {} published, {} dropped, {} objects",
            self.poses_in, self.published, self.dropped, self.objects
        )
    }
}

/// The Zenoh side: the node's token and the objects' publishers, created lazily.
struct Bridge {
    session: Session,
    node: Node,
    _node_token: LivelinessToken,
    objects: HashMap<String, ObjectTopics>,
    next_entity: usize,
    clock: RealtimeMap,
    frame_id: String,
    counts: Counts,
}

impl Bridge {
    /// Declares the node (entity 0) on `session`.
    fn new(session: Session, options: &Options) -> Result<Self> {
        let node = Node {
            domain: options.domain,
            zid: session.zid().to_string(),
            id: 0,
            enclave: "/".into(),
            namespace: "/".into(),
            name: NODE_NAME.into(),
        };
        let token = node.node_token();
        let node_token = session
            .liveliness()
            .declare_token(token.clone())
            .wait()
            .map_err(|e| anyhow!("cannot declare the liveliness token {token}: {e}"))?;
        Ok(Self {
            session,
            node,
            _node_token: node_token,
            objects: HashMap::new(),
            next_entity: 1,
            clock: RealtimeMap::new(),
            frame_id: options.frame_id.clone(),
            counts: Counts::default(),
        })
    }

    /// The topics of `name`, declared when it first appears (`None` past the limit).
    fn topics(&mut self, name: &str) -> Result<Option<&mut ObjectTopics>> {
        if !self.objects.contains_key(name) {
            if self.objects.len() >= MAX_TOPIC_OBJECTS {
                return Ok(None);
            }
            let topics = ObjectTopics::declare(&self.session, &self.node, self.next_entity, name)?;
            tracing::info!("publishing /photopose/{name}/pose and /photopose/{name}/status");
            self.next_entity += 2;
            self.objects.insert(name.to_owned(), topics);
            self.counts.objects = self.objects.len();
        }
        Ok(self.objects.get_mut(name))
    }

    /// Publishes every object of a set; a failure costs that pose only.
    fn publish_set(&mut self, set: &PoseSet) {
        self.clock.refresh();
        for object in set.objects() {
            match self.publish(object.name(), &object.pose) {
                Ok(()) => self.counts.published += 1,
                Err(e) => {
                    self.counts.dropped += 1;
                    tracing::warn!("{}: {e:#}", object.name());
                }
            }
        }
    }

    /// Publishes one object's pose and status.
    fn publish(&mut self, name: &str, pose: &PoseMsg) -> Result<()> {
        let stamp = Stamp::from_ns(self.clock.realtime(pose.capture_time_ns));
        let frame_id = self.frame_id.clone();
        let Some(topics) = self.topics(name)? else {
            bail!("more than {MAX_TOPIC_OBJECTS} objects: not published");
        };
        pose_stamped(&mut topics.pose.buf, stamp, &frame_id, pose);
        topics.pose.put()?;
        diagnostic_status(&mut topics.status.buf, name, pose);
        topics.status.put()
    }
}

/// Takes every waiting set into `pending`, keeping the newest [`BACKLOG`].
fn drain(sub: &PoseSubscriber, pending: &mut VecDeque<PoseSet>, counts: &mut Counts) -> Result<()> {
    while let Some(set) = receive_poses(sub)? {
        counts.poses_in += set.objects().len() as u64;
        if pending.len() == BACKLOG {
            if let Some(old) = pending.pop_front() {
                counts.dropped += old.objects().len() as u64;
            }
        }
        pending.push_back(set);
    }
    Ok(())
}

/// Bridges until interrupted (Ctrl-C, SIGTERM) or `options.seconds` pass; logs the
/// counts every 2 s and returns them.
pub fn run(options: &Options) -> Result<Counts> {
    options.check()?;
    let ipc = Ipc::new("photopose-bridge")?;
    let sub = ipc.pose_subscriber(&options.service)?;
    let wake = ipc.wake(&options.service)?;
    let session = options.network.open()?;
    tracing::info!("Zenoh session {} open, domain {}", session.zid(), options.domain);
    let mut bridge = Bridge::new(session.clone(), options)?;
    let (start, mut logged) = (Instant::now(), Instant::now());
    let mut pending = VecDeque::with_capacity(BACKLOG);
    let mut counts = Counts::default();
    while ipc.wait_for(&wake, Duration::from_millis(100)) {
        drain(&sub, &mut pending, &mut counts)?;
        for set in pending.drain(..) {
            bridge.publish_set(&set);
        }
        if logged.elapsed() >= LOG_EVERY {
            logged = Instant::now();
            tracing::info!("bridge: {}, {} peers", total(&counts, &bridge.counts), peers(&session));
        }
        if options.seconds > 0.0 && start.elapsed().as_secs_f64() >= options.seconds {
            break;
        }
    }
    let counts = total(&counts, &bridge.counts);
    drop(bridge);
    if let Err(e) = session.close().wait() {
        tracing::warn!("closing the Zenoh session: {e}");
    }
    Ok(counts)
}

/// The iceoryx2 side's counts merged with the Zenoh side's.
fn total(ipc: &Counts, zenoh: &Counts) -> Counts {
    Counts {
        poses_in: ipc.poses_in,
        published: zenoh.published,
        dropped: ipc.dropped + zenoh.dropped,
        objects: zenoh.objects,
    }
}

/// Zenoh peers and routers the session is connected to.
fn peers(session: &Session) -> usize {
    let info = session.info();
    info.peers_zid().wait().count() + info.routers_zid().wait().count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ids_are_checked() {
        for good in ["hand", "base_link", "robot/hand"] {
            assert!(check_frame_id(good).is_ok(), "{good}");
        }
        for bad in ["", "/hand", "my hand", "händ"] {
            let e = check_frame_id(bad).expect_err(bad).to_string();
            assert!(e.starts_with("bad frame id"), "{e}");
        }
    }

    #[test]
    fn options_are_checked_before_anything_opens() {
        let options = Options {
            network: Network::default(),
            domain: 0,
            frame_id: "hand".into(),
            service: "photopose/poses".into(),
            seconds: 0.0,
        };
        assert!(options.check().is_ok());
        let bad_domain = Options {
            domain: 233,
            ..options.clone()
        };
        assert!(bad_domain.check().is_err());
        let bad_seconds = Options {
            seconds: f64::NAN,
            ..options
        };
        assert!(bad_seconds.check().is_err());
    }
}
