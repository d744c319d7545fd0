//! iceoryx2 plumbing shared by every process: one node per process, the three services
//! of DESIGN §4 opened with the same settings by publishers and subscribers (so any
//! start order works), and clean-up of what crashed processes left behind.
//!
//! Beside each publish-subscribe service an event service of the same name wakes the
//! subscribers when a sample was sent ([`Wake`]), so they need not poll. Clients that do
//! not listen (Python, C++) lose nothing: the samples are there either way.

use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory;

use crate::transport::messages::{FrameHeader, PoseSet, FRAMES_SERVICE};

/// What went wrong with iceoryx2: the step that failed, what it concerned, and
/// iceoryx2's own error.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// A node or service name iceoryx2 does not accept.
    #[error("{kind} name {name}: {detail}")]
    Name {
        /// `"node"` or `"service"`.
        kind: &'static str,
        /// The name given.
        name: String,
        /// iceoryx2's error.
        detail: String,
    },
    /// A step of setting up or using a node, service or port failed.
    #[error("cannot {step}: {detail}")]
    Failed {
        /// What was attempted, e.g. `open photopose/poses`.
        step: String,
        /// iceoryx2's error.
        detail: String,
    },
}

impl IpcError {
    /// iceoryx2 refused the `kind` (`"node"` or `"service"`) name `name`.
    fn name(kind: &'static str, name: &str, error: impl std::fmt::Debug) -> Self {
        IpcError::Name {
            kind,
            name: name.into(),
            detail: format!("{error:?}"),
        }
    }

    /// `step` failed with iceoryx2's `error`.
    pub(crate) fn failed(step: impl Into<String>, error: impl std::fmt::Debug) -> Self {
        IpcError::Failed {
            step: step.into(),
            detail: format!("{error:?}"),
        }
    }
}

/// The result of an iceoryx2 step.
pub type Result<T, E = IpcError> = std::result::Result<T, E>;

/// The shared-memory transport of this crate.
pub type Transport = ipc::Service;
/// Publishes side-by-side frames.
pub type FramePublisher = Publisher<Transport, [u8], FrameHeader>;
/// Receives side-by-side frames.
pub type FrameSubscriber = Subscriber<Transport, [u8], FrameHeader>;
/// Publishes pose sets (estimates or ground truth).
pub type PosePublisher = Publisher<Transport, PoseSet, ()>;
/// Receives pose sets.
pub type PoseSubscriber = Subscriber<Transport, PoseSet, ()>;

/// Frames a subscriber holds before the oldest is overwritten: a slow subscriber loses
/// old frames, never memory, and never blocks the camera.
const FRAME_BUFFER: usize = 2;
/// Poses a subscriber holds (about a second of a 60 fps stream).
const POSE_BUFFER: usize = 64;

/// One process's iceoryx2 node.
pub struct Ipc {
    node: Node<Transport>,
}

impl Ipc {
    /// Creates the node `name` and removes resources of dead photopose processes.
    pub fn new(name: &str) -> Result<Self> {
        // iceoryx2's own notices (e.g. "no config file loaded") are not the user's business.
        set_log_level(LogLevel::Error);
        let node_name = NodeName::new(name).map_err(|e| IpcError::name("node", name, e))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
            .create::<Transport>()
            .map_err(|e| IpcError::failed(format!("create the iceoryx2 node {name}"), e))?;
        let cleaned = node.try_cleanup_dead_nodes();
        tracing::debug!("iceoryx2 clean-up of dead nodes: {cleaned:?}");
        Ok(Self { node })
    }

    /// Waits up to `timeout`; false once the process was asked to terminate (Ctrl-C, SIGTERM).
    pub fn wait(&self, timeout: Duration) -> bool {
        self.node.wait(timeout).is_ok()
    }

    fn service_name(name: &str) -> Result<ServiceName> {
        ServiceName::new(name).map_err(|e| IpcError::name("service", name, e))
    }

    /// The frames service.
    pub fn frames(&self) -> Result<PortFactory<Transport, [u8], FrameHeader>> {
        self.frames_on(FRAMES_SERVICE)
    }

    /// A frames service of another name, with the same settings (tools, tests).
    pub fn frames_on(&self, service: &str) -> Result<PortFactory<Transport, [u8], FrameHeader>> {
        self.node
            .service_builder(&Self::service_name(service)?)
            .publish_subscribe::<[u8]>()
            .user_header::<FrameHeader>()
            .subscriber_max_buffer_size(FRAME_BUFFER)
            .history_size(0)
            .enable_safe_overflow(true)
            .max_publishers(2)
            .max_subscribers(8)
            .open_or_create()
            .map_err(|e| IpcError::failed(format!("open {service}"), e))
    }

    /// A pose service ([`crate::transport::messages::POSES_SERVICE`] or [`crate::transport::messages::TRUTH_SERVICE`]).
    pub fn poses(&self, service: &str) -> Result<PortFactory<Transport, PoseSet, ()>> {
        self.node
            .service_builder(&Self::service_name(service)?)
            .publish_subscribe::<PoseSet>()
            .subscriber_max_buffer_size(POSE_BUFFER)
            .history_size(1)
            .enable_safe_overflow(true)
            .max_publishers(2)
            .max_subscribers(16)
            .open_or_create()
            .map_err(|e| IpcError::failed(format!("open {service}"), e))
    }

    /// A frame publisher for side-by-side images of `bytes` bytes.
    pub fn frame_publisher(&self, bytes: usize) -> Result<FramePublisher> {
        self.frames()?
            .publisher_builder()
            .initial_max_slice_len(bytes)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| IpcError::failed("create the frame publisher", e))
    }

    /// A subscriber to the frames service that keeps the newest two frames.
    pub fn frame_subscriber(&self) -> Result<FrameSubscriber> {
        self.frames()?
            .subscriber_builder()
            .buffer_size(FRAME_BUFFER)
            .create()
            .map_err(|e| IpcError::failed(format!("subscribe to {FRAMES_SERVICE}"), e))
    }

    /// A publisher on the pose service `service`.
    pub fn pose_publisher(&self, service: &str) -> Result<PosePublisher> {
        self.poses(service)?
            .publisher_builder()
            .create()
            .map_err(|e| IpcError::failed(format!("publish on {service}"), e))
    }

    /// A subscriber to the pose service `service` (it keeps up to 64 unread poses).
    pub fn pose_subscriber(&self, service: &str) -> Result<PoseSubscriber> {
        self.poses(service)?
            .subscriber_builder()
            .create()
            .map_err(|e| IpcError::failed(format!("subscribe to {service}"), e))
    }
}

/// Listens for a service's wake-up events: [`Ipc::wait_for`] sleeps on it.
pub type Wake = Listener<Transport>;
/// Notifies a service's [`Wake`] listeners: [`wake_up`] after each send.
pub type Waker = Notifier<Transport>;

impl Ipc {
    fn events(&self, service: &str) -> Result<iceoryx2::service::port_factory::event::PortFactory<Transport>> {
        self.node
            .service_builder(&Self::service_name(service)?)
            .event()
            .max_notifiers(4)
            .max_listeners(16)
            .open_or_create()
            .map_err(|e| IpcError::failed(format!("open the events of {service}"), e))
    }

    /// Wakes the listeners of `service` ([`Ipc::wake`]) after each send.
    pub fn waker(&self, service: &str) -> Result<Waker> {
        self.events(service)?
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::failed(format!("notify on {service}"), e))
    }

    /// Woken when a sample was sent on `service`.
    pub fn wake(&self, service: &str) -> Result<Wake> {
        self.events(service)?
            .listener_builder()
            .create()
            .map_err(|e| IpcError::failed(format!("listen on {service}"), e))
    }

    /// Sleeps until `wake` fires or `timeout` passes; false once the process was asked to
    /// terminate.
    pub fn wait_for(&self, wake: &Wake, timeout: Duration) -> bool {
        if wake.timed_wait(|_| {}, timeout).is_err() {
            // Interrupted (a signal) or broken: fall back to the node's own wait.
            return self.wait(Duration::from_millis(1));
        }
        self.wait(Duration::ZERO)
    }
}

/// Tells the listeners that a sample was sent; a failure only costs them a poll period.
pub fn wake_up(waker: &Waker) {
    if let Err(e) = waker.notify() {
        tracing::debug!("cannot notify listeners: {e:?}");
    }
}

/// Sends one frame's pose set.
pub fn send_poses(publisher: &PosePublisher, poses: &PoseSet) -> Result<()> {
    let sample = publisher
        .loan_uninit()
        .map_err(|e| IpcError::failed("loan a pose sample", e))?;
    sample
        .write_payload(*poses)
        .send()
        .map_err(|e| IpcError::failed("send a pose set", e))?;
    Ok(())
}

/// Takes the next pose set that arrived on `subscriber`, if any.
pub fn receive_poses(subscriber: &PoseSubscriber) -> Result<Option<PoseSet>> {
    let sample = subscriber
        .receive()
        .map_err(|e| IpcError::failed("receive a pose set", e))?;
    Ok(sample.map(|s| *s.payload()))
}
