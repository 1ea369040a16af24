//! What the server and the client share: the node's configuration as a ROS node reads it
//! from the environment, the DDS participant behind it, its spinner thread, and the QoS.
//!
//! * `ROS_DOMAIN_ID` (unset or empty: 0; otherwise 0..=232, anything else is
//!   [`Ros2Error::DomainId`]). ros2-client's `Context::new()` ignores it, so the domain is
//!   always passed explicitly.
//! * `ROS_AUTOMATIC_DISCOVERY_RANGE` (unset, empty, `SUBNET`, `SYSTEM_DEFAULT`: subnet;
//!   `LOCALHOST`: loopback only; `OFF` and anything else: [`Ros2Error::DiscoveryRange`]).
//!   RustDDS does not read it. For `LOCALHOST` the participant is built with
//!   `DomainParticipantBuilder::with_only_networks([127.0.0.1])`: it advertises only its
//!   loopback locators and joins no multicast group (the loopback interface has no
//!   multicast), and it finds the other participants of the host by sending its SPDP
//!   announcements to the well-known unicast ports of participant ids 0..=11 on 127.0.0.1
//!   (RustDDS's `same_host_loopback`, on by default), which is where Fast DDS in
//!   `LOCALHOST` mode listens and announces too. Nothing leaves the machine. More than 12
//!   participants of one domain on one host are not all probed by RustDDS; those it does
//!   not probe still find it when they announce themselves.
//!   `ROS_STATIC_PEERS` is not implemented.

use std::future::Future;
use std::net::{IpAddr, Ipv4Addr};
use std::pin::pin;
use std::sync::Arc;
use std::task::{Context as TaskContext, Poll, Wake, Waker};
use std::thread::{self, JoinHandle, Thread};
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::{DomainParticipant, DomainParticipantBuilder};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{Context, Name, Node, NodeName, NodeOptions, QosProfile};
use tracing::{debug, warn};

use crate::Ros2Error;

/// Which peers discovery reaches (`ROS_AUTOMATIC_DISCOVERY_RANGE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// This host only, over loopback.
    Localhost,
    /// The subnet (multicast on every interface): ROS's default.
    Subnet,
}

impl DiscoveryRange {
    /// Reads `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    pub fn from_env() -> Result<Self, Ros2Error> {
        Self::parse(std::env::var("ROS_AUTOMATIC_DISCOVERY_RANGE").ok().as_deref())
    }

    /// A value of `ROS_AUTOMATIC_DISCOVERY_RANGE` (`None`: unset).
    pub fn parse(value: Option<&str>) -> Result<Self, Ros2Error> {
        match value.map(str::trim) {
            None | Some("" | "SUBNET" | "SYSTEM_DEFAULT") => Ok(Self::Subnet),
            Some("LOCALHOST") => Ok(Self::Localhost),
            Some(other) => Err(Ros2Error::DiscoveryRange {
                value: other.to_owned(),
            }),
        }
    }
}

/// Reads `ROS_DOMAIN_ID`.
pub fn domain_id_from_env() -> Result<u16, Ros2Error> {
    parse_domain_id(std::env::var("ROS_DOMAIN_ID").ok().as_deref())
}

/// A value of `ROS_DOMAIN_ID` (`None`: unset); ROS allows 0..=232 (the UDP port mapping
/// ends there).
pub fn parse_domain_id(value: Option<&str>) -> Result<u16, Ros2Error> {
    let Some(text) = value.map(str::trim).filter(|t| !t.is_empty()) else {
        return Ok(0);
    };
    text.parse::<u16>()
        .ok()
        .filter(|id| *id <= 232)
        .ok_or_else(|| Ros2Error::DomainId { value: text.to_owned() })
}

/// The node: its name and where it lives on the DDS network.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeConfig {
    /// Node name (letters, digits, `_`; not starting with a digit).
    pub name: String,
    /// Node namespace, `/` or `/a/b`.
    pub namespace: String,
    /// `None`: `ROS_DOMAIN_ID`.
    pub domain_id: Option<u16>,
    /// `None`: `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    pub discovery: Option<DiscoveryRange>,
}

impl NodeConfig {
    /// A node of this name in `/`, configured by the environment.
    pub fn named(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            namespace: "/".to_owned(),
            domain_id: None,
            discovery: None,
        }
    }
}

/// A running node: the ros2-client node and the thread that spins it (discovery events,
/// which the waits and the match counts need). Dropping it drops the node, which stops the
/// spinner, and joins the spinner thread. Owners drop their readers and writers first
/// (declare this field last): RustDDS logs an error for every entity that outlives its
/// participant's event loop.
pub(crate) struct RunningNode {
    /// `Some` until dropped: the node must go before the spinner is joined.
    node: Option<Node>,
    /// The node's DDS participant (a handle), for what ros2-client does not expose.
    pub participant: DomainParticipant,
    spinner: Option<JoinHandle<()>>,
}

impl RunningNode {
    /// Creates the participant and the node and starts its spinner thread. Rosout and the
    /// parameter services are off: the planner logs with `tracing` and has no ROS
    /// parameters, and each would add endpoints that every peer must discover.
    pub fn start(config: &NodeConfig) -> Result<Self, Ros2Error> {
        let domain_id = match config.domain_id {
            Some(id) => id,
            None => domain_id_from_env()?,
        };
        let discovery = match config.discovery {
            Some(range) => range,
            None => DiscoveryRange::from_env()?,
        };
        let mut builder = DomainParticipantBuilder::new(domain_id);
        if discovery == DiscoveryRange::Localhost {
            builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        let participant = builder
            .build()
            .map_err(|e| Ros2Error::create("the DDS participant", e))?;
        let context = Context::from_domain_participant(participant.clone())
            .map_err(|e| Ros2Error::create("the ROS context", e))?;
        let name = NodeName::new(&config.namespace, &config.name).map_err(|e| Ros2Error::Name {
            name: format!("{}/{}", config.namespace, config.name),
            reason: e.to_string(),
        })?;
        let options = NodeOptions::new().enable_rosout(false).start_parameter_services(false);
        let mut node = context
            .new_node(name, options)
            .map_err(|e| Ros2Error::create("the ROS node", e))?;
        let spinner = node.spinner().map_err(|e| Ros2Error::create("the node's spinner", e))?;
        let thread_name = format!("ros2-spin-{}", config.name);
        let spinner = thread::Builder::new()
            .name(thread_name)
            .spawn(move || {
                if let Err(e) = futures::executor::block_on(spinner.spin()) {
                    warn!("ROS 2 spinner stopped: {e}");
                }
            })
            .map_err(|source| Ros2Error::Io {
                what: "the spinner thread",
                source,
            })?;
        debug!(domain_id, ?discovery, node = %config.name, "ROS 2 node started");
        Ok(Self {
            node: Some(node),
            participant,
            spinner: Some(spinner),
        })
    }

    pub fn node(&self) -> &Node {
        self.node.as_ref().expect("the node lives until dropped")
    }

    pub fn node_mut(&mut self) -> &mut Node {
        self.node.as_mut().expect("the node lives until dropped")
    }

    /// Waits, at most `timeout`, until `found` holds, re-checking it whenever the spinner
    /// reports a discovery event. `found` must read state that discovery updates before the
    /// event is sent (the DDS discovery database, the node's match counts).
    ///
    /// ros2-client's own waits (`Client::wait_for_service`, `wait_for_publisher`, ...) can
    /// miss their match for good: the node's event channel holds 8 events and drops the
    /// rest, ROS discovery traffic fills it, and those waits re-check only on an event of
    /// the matching kind. Here every event (or a full channel) leads to a re-check after the
    /// channel is drained, and a re-check every [`RECHECK`] guards against events lost
    /// before this wait subscribed.
    pub fn wait_until(&self, timeout: Duration, mut found: impl FnMut() -> bool) -> bool {
        let deadline = Instant::now() + timeout;
        // Subscribed before the first check, so that a change in between wakes us.
        let events = self.node().status_receiver();
        loop {
            if found() {
                return true;
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return false;
            }
            let slice = remaining.min(RECHECK);
            match &events {
                Some(events) if !events.is_closed() => {
                    let _ = block_on_timeout(events.recv(), slice);
                    while events.try_recv().is_ok() {}
                }
                _ => thread::park_timeout(slice),
            }
        }
    }
}

impl Drop for RunningNode {
    /// The node's drop tells the spinner to stop (while it still listens, so that
    /// ros2-client logs no error); then the thread is joined.
    fn drop(&mut self) {
        drop(self.node.take());
        if let Some(handle) = self.spinner.take() {
            let _ = handle.join();
        }
    }
}

/// A name such as `/hmdp/plan` for ros2-client.
pub(crate) fn ros_name(full: &str) -> Result<Name, Ros2Error> {
    Name::parse(full).map_err(|e| Ros2Error::Name {
        name: full.to_owned(),
        reason: e.to_string(),
    })
}

/// How often [`RunningNode::wait_until`] re-checks without an event.
const RECHECK: Duration = Duration::from_millis(200);

/// A remote endpoint's kind, for [`discovered`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endpoint {
    Reader,
    Writer,
}

/// Whether a remote `kind` endpoint on DDS topic `topic` with DDS type `type_name` is in the
/// participant's discovery database.
pub(crate) fn discovered(participant: &DomainParticipant, kind: Endpoint, topic: &str, type_name: &str) -> bool {
    match kind {
        Endpoint::Reader => participant.discovered_readers().iter().any(|r| {
            r.subscription_topic_data.topic_name == topic && r.subscription_topic_data.type_name() == type_name
        }),
        Endpoint::Writer => participant
            .discovered_writers()
            .iter()
            .any(|w| w.publication_topic_data.topic_name == topic && w.publication_topic_data.type_name == type_name),
    }
}

/// Reliable, volatile, keep-last `depth`: rclpy's default for topics and services
/// (depth 10). ros2-client's own default for subscriptions is best effort depth 1, which
/// would match rclpy's reliable writers but lose samples.
pub(crate) fn reliable_qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// The depth of the service's readers and writers. Reliability and durability are those
/// of rclpy's services (reliable, volatile), the ones peers must agree on; the depth is
/// not matched between peers, and every client's reader sees every client's answers on
/// the one reply topic, so it is deeper than rclpy's 10 for bursts of many vehicles.
pub(crate) const SERVICE_DEPTH: usize = 100;
/// The depth of the published topics (rclpy's default).
pub(crate) const TOPIC_DEPTH: usize = 10;

/// Wakes the thread that blocks in [`block_on_timeout`].
struct ThreadWaker(Thread);

impl Wake for ThreadWaker {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        self.0.unpark();
    }
}

/// Runs `future` on this thread until it completes (`Some`) or `timeout` passes (`None`):
/// the thread parks between polls, so waiting costs nothing and needs no timer thread.
pub(crate) fn block_on_timeout<F: Future>(future: F, timeout: Duration) -> Option<F::Output> {
    let deadline = Instant::now() + timeout;
    let waker = Waker::from(Arc::new(ThreadWaker(thread::current())));
    let mut cx = TaskContext::from_waker(&waker);
    let mut future = pin!(future);
    loop {
        if let Poll::Ready(output) = future.as_mut().poll(&mut cx) {
            return Some(output);
        }
        let now = Instant::now();
        if now >= deadline {
            return None;
        }
        thread::park_timeout(deadline - now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domain_ids() {
        assert_eq!(parse_domain_id(None).unwrap(), 0);
        assert_eq!(parse_domain_id(Some("")).unwrap(), 0);
        assert_eq!(parse_domain_id(Some(" 42 ")).unwrap(), 42);
        assert_eq!(parse_domain_id(Some("232")).unwrap(), 232);
        for bad in ["233", "-1", "abc", "70000"] {
            assert!(
                matches!(parse_domain_id(Some(bad)), Err(Ros2Error::DomainId { .. })),
                "{bad}"
            );
        }
    }

    #[test]
    fn discovery_ranges() {
        assert_eq!(DiscoveryRange::parse(None).unwrap(), DiscoveryRange::Subnet);
        assert_eq!(DiscoveryRange::parse(Some("SUBNET")).unwrap(), DiscoveryRange::Subnet);
        assert_eq!(
            DiscoveryRange::parse(Some("LOCALHOST")).unwrap(),
            DiscoveryRange::Localhost
        );
        assert!(DiscoveryRange::parse(Some("OFF")).is_err());
        assert!(DiscoveryRange::parse(Some("localhost")).is_err());
    }

    #[test]
    fn block_on_timeout_returns_ready_and_times_out() {
        assert_eq!(block_on_timeout(async { 7 }, Duration::from_millis(1)), Some(7));
        assert_eq!(
            block_on_timeout(std::future::pending::<()>(), Duration::from_millis(5)),
            None
        );
    }
}
