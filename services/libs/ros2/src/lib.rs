//! The planner as a ROS 2 node, and its ROS 2 client, on `ros2-client` (pure Rust over
//! RustDDS: no ROS installation, interoperates with rclpy/rclcpp on Fast DDS).
//!
//! * [`msg`]: the `hmdp_msgs` messages (`ros2/hmdp_msgs/`) and `visualization_msgs/Marker`
//!   as serde structs that RustDDS writes byte for byte as rosidl does (CDR).
//! * Conversions (`From` / `TryFrom`) in both directions between those and the protocol's
//!   messages; a ROS message the protocol cannot hold is a [`ConvertError`] carrying the
//!   typed rejection.
//! * [`markers`]: a request and its answer as RViz markers in the frame [`FRAME_ID`].
//! * [`PlanServer`]: the node that serves [`SERVICE_NAME`] and publishes every
//!   answer on [`DECISIONS_TOPIC`] and its markers on [`MARKERS_TOPIC`].
//! * [`PlanClient`]: a blocking client for vehicles and simulators, and
//!   [`DecisionSubscriber`].
//!
//! Both sides read `ROS_DOMAIN_ID` and `ROS_AUTOMATIC_DISCOVERY_RANGE` like a ROS node
//! ([`NodeConfig`], [`DiscoveryRange`]); the threads ros2-client needs are inside, callers see synchronous calls.

mod client;
mod convert;
pub mod incoming;
pub mod markers;
pub mod msg;
mod node;
mod server;

use std::time::Duration;

use thiserror::Error;

pub use client::{ClientOptions, DecisionSubscriber, PlanClient};
pub use convert::ConvertError;
pub use node::{DiscoveryRange, NodeConfig};
pub use server::{Incoming, MarkersFor, PlanServer, Reply, ServerCounters, ServerOptions};

/// The planner's service (`hmdp_msgs/srv/Plan`).
pub const SERVICE_NAME: &str = "/hmdp/plan";
/// Every answer the server sends, also published here (`hmdp_msgs/msg/PlanResponse`).
pub const DECISIONS_TOPIC: &str = "/hmdp/decisions";
/// The markers of every answer (`visualization_msgs/msg/MarkerArray`).
pub const MARKERS_TOPIC: &str = "/hmdp/plan_markers";
/// The server's node name unless told otherwise.
pub const DEFAULT_SERVER_NODE: &str = "hmdp_planner";
/// The frame of the markers: x along the road, y across it (lane `i` has its centre at
/// `(lanes - i) * lane_width_m`, so y grows to the left as in ROS), z up; origin at x = 0 of
/// the requests' road coordinates and y = 0. A vehicle that wants the markers on its map
/// publishes a transform from its map frame to this one.
pub const FRAME_ID: &str = "hmdp_road";

/// Log filter directives (tracing's `EnvFilter` syntax) for a process that runs a node:
/// RustDDS logs every discovery step at INFO, warns about the participant's own reflected
/// endpoints, and logs an ERROR when a loopback-only participant closes and leaves a
/// multicast group it never joined; ros2-client warns for every request of a RustDDS client
/// (which sends no related sample identity; the request's own identity is used, correctly).
/// None of it is the operator's business.
pub const QUIET_LOG_DIRECTIVES: &str =
    "rustdds=error,rustdds::network::udp_listener=off,ros2_client=warn,ros2_client::service::wrappers=error";

/// Why a ROS 2 call failed.
#[derive(Debug, Error)]
pub enum Ros2Error {
    /// `ROS_DOMAIN_ID` is not a domain id (0..=232).
    #[error("ROS_DOMAIN_ID={value:?} is not a ROS domain id (0..=232)")]
    DomainId { value: String },
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE` holds a value this crate does not implement.
    #[error("ROS_AUTOMATIC_DISCOVERY_RANGE={value:?} is not supported (LOCALHOST, SUBNET, SYSTEM_DEFAULT)")]
    DiscoveryRange { value: String },
    /// A node, topic or service name that ROS does not accept.
    #[error("invalid ROS name {name:?}: {reason}")]
    Name { name: String, reason: String },
    /// The DDS participant, a node, topic, reader or writer could not be created.
    #[error("cannot create {what}: {reason}")]
    Create { what: &'static str, reason: String },
    /// A background thread or its event loop could not be set up.
    #[error("cannot start {what}: {source}")]
    Io {
        what: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// No peer of this service or topic was matched (and, for the service, answered a
    /// readiness probe) in time.
    #[error("no peer of {service} matched within {waited:?}")]
    ServiceUnavailable { service: &'static str, waited: Duration },
    /// A request could not be written.
    #[error("cannot send the request: {0}")]
    Send(String),
    /// The answer arrived but its CDR did not decode (a peer with another `hmdp_msgs`).
    #[error("undecodable response: {0}")]
    UndecodableResponse(String),
    /// The answer decoded but the protocol cannot hold it (list over capacity, unknown code).
    #[error("invalid response: {0}")]
    InvalidResponse(#[from] ConvertError),
    /// Waiting on the client's reply reader failed (its mio poll).
    #[error("the ROS 2 client cannot wait for answers: {0}")]
    Poll(#[source] std::io::Error),
}

impl Ros2Error {
    pub(crate) fn create(what: &'static str, error: impl std::fmt::Display) -> Self {
        Self::Create {
            what,
            reason: error.to_string(),
        }
    }
}
