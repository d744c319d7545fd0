//! The bridge's ROS 2 entities on Zenoh: the node and, per object, a pose and a status
//! publisher, each announced by an rmw_zenoh liveliness token.

use anyhow::{anyhow, Result};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

use super::clock::realtime_ns;
use super::msgs::{RosType, DIAGNOSTIC_STATUS, POSE_STAMPED};
use super::names::{attachment, gid, topic_key, Node, Qos};

/// One ROS 2 publisher: the Zenoh publisher, its liveliness token, GID and sequence.
pub struct RosPublisher {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    sequence: i64,
    /// The message being serialised (reused from sample to sample).
    pub buf: Vec<u8>,
}

impl RosPublisher {
    /// Declares the publisher `entity` of `node` on `topic` and its token. Congestion
    /// drops samples: a stalled network never blocks the bridge.
    pub fn declare(session: &Session, node: &Node, entity: usize, topic: &str, ty: &RosType) -> Result<Self> {
        let key = topic_key(node.domain, topic, ty);
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Drop)
            .wait()
            .map_err(|e| anyhow!("cannot declare the Zenoh publisher {key}: {e}"))?;
        let token = node.publisher_token(entity, topic, ty, &Qos::DEFAULT);
        let gid = gid(&token);
        let liveliness = session
            .liveliness()
            .declare_token(token.clone())
            .wait()
            .map_err(|e| anyhow!("cannot declare the liveliness token {token}: {e}"))?;
        Ok(Self {
            publisher,
            _token: liveliness,
            gid,
            sequence: 0,
            buf: Vec::with_capacity(256),
        })
    }

    /// Publishes [`RosPublisher::buf`] with the next sequence number (from 1).
    pub fn put(&mut self) -> Result<()> {
        self.sequence += 1;
        let attachment = attachment(self.sequence, realtime_ns(), &self.gid);
        self.publisher
            .put(self.buf.clone())
            .attachment(attachment)
            .wait()
            .map_err(|e| anyhow!("cannot publish on {}: {e}", self.publisher.key_expr()))
    }
}

/// An object's topics: `/photopose/<object>/pose` and `/photopose/<object>/status`.
pub struct ObjectTopics {
    /// `geometry_msgs/msg/PoseStamped`.
    pub pose: RosPublisher,
    /// `diagnostic_msgs/msg/DiagnosticStatus`.
    pub status: RosPublisher,
}

/// The topic of `object`'s `leaf` (`pose` or `status`).
pub fn topic(object: &str, leaf: &str) -> String {
    format!("/photopose/{object}/{leaf}")
}

impl ObjectTopics {
    /// Declares `object`'s publishers as entities `first` and `first + 1` of `node`.
    pub fn declare(session: &Session, node: &Node, first: usize, object: &str) -> Result<Self> {
        Ok(Self {
            pose: RosPublisher::declare(session, node, first, &topic(object, "pose"), &POSE_STAMPED)?,
            status: RosPublisher::declare(session, node, first + 1, &topic(object, "status"), &DIAGNOSTIC_STATUS)?,
        })
    }
}
