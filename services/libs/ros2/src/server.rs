//! [`PlanServer`]: the planner as a ROS 2 node.
//!
//! It serves [`SERVICE_NAME`] (`hmdp_msgs/srv/Plan`) and publishes
//! every answer on [`DECISIONS_TOPIC`] and its markers on
//! [`MARKERS_TOPIC`].
//!
//! Threads: `ros2-server` sleeps in a mio poll on the request reader, takes each request,
//! converts it and calls the handler, which must return at once (the planner queues the
//! request); the [`Reply`] is called later from any thread (a worker, the watchdog) and
//! writes the answer itself, so the receiving thread never waits for a solve or a write.
//! `ros2-spin-<node>` runs ros2-client's spinner (discovery events, which the waits use).
//! RustDDS adds its own event loop and discovery threads. Decisions are published always;
//! markers only while a subscriber is discovered (building them costs far more).
//!
//! QoS, chosen to match rclpy's defaults (peers must agree on reliability and durability,
//! not on depth): the service's request reader and reply writer are reliable, volatile,
//! keep-last 100 (rclpy: 10; deeper because a client's first answer, and every answer to
//! a participant with several reply readers, goes to every client's reply reader); the two topics are reliable, volatile, keep-last 10. The service mapping is
//! DDS-RPC "Enhanced" (the request id in the inline QoS), the one rmw_fastrtps uses.
//!
//! A payload that does not decode as a `Plan` request (a peer with another `hmdp_msgs`)
//! still has its RMW request id: the handler gets [`Incoming::Undecodable`] with a
//! `malformed` rejection (and the ids read before the fault), so it is answered like any
//! request. A request whose lists exceed their bounds is undecodable with
//! `capacity_exceeded` naming the list. Nothing a peer sends stops the node.

use std::collections::BTreeMap;
use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use protocol::{PlanRequest, PlanResponse, RejectReason, Rejected};
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token, Waker};
use ros2_client::dds::rustdds::GUID;
use ros2_client::{Node, Publisher, RmwRequestId, Server, ServiceMapping};
use tracing::{debug, error, warn};

use crate::incoming::IncomingRequest;
use crate::markers::plan_markers;
use crate::msg::viz::{MarkerArray, Time};
use crate::msg::{self, plan_service_type_name};
use crate::node::{discovered, reliable_qos, ros_name, Endpoint, NodeConfig, RunningNode, SERVICE_DEPTH, TOPIC_DEPTH};
use crate::{Ros2Error, DECISIONS_TOPIC, DEFAULT_SERVER_NODE, MARKERS_TOPIC, SERVICE_NAME};

/// Sends the answer of one request: to its client, then on the topics. Call it exactly
/// once, from any thread, at any time (also after the deadline, and after the server has
/// stopped, when it sends what it still can). It never panics. It takes microseconds, except
/// for the first answer to a client whose reply reader is not yet discovered: that one
/// waits up to 100 ms for it, as rmw_fastrtps does (see `Shared::await_reply_reader`).
pub type Reply = Box<dyn FnOnce(PlanResponse) + Send>;

/// What the handler gets for each request.
#[derive(Debug, Clone, PartialEq)]
// Moved once into the handler, which hands the request on by value (as the planner's other
// front ends do): a box would only add an allocation per request.
#[allow(clippy::large_enum_variant)]
pub enum Incoming {
    /// A request the planner must judge (its own validation decides what is valid).
    Request(PlanRequest),
    /// A request the protocol cannot hold (a list over its capacity, or a payload that did
    /// not decode): answer it with this rejection and these ids.
    Undecodable {
        vehicle_id: u64,
        sequence: u64,
        rejected: Rejected,
    },
}

/// Whose answers get markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkersFor {
    /// No markers.
    Nobody,
    /// Every answer. With several vehicles, each array's `DELETEALL` clears the previous
    /// vehicle's markers: RViz shows the latest answer.
    Everyone,
    /// The answers of this vehicle only.
    Vehicle(u64),
}

/// How to start a [`PlanServer`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServerOptions {
    /// Default: node `hmdp_planner` in `/`, domain and discovery from the environment.
    pub node: NodeConfig,
    /// Publish every answer on [`DECISIONS_TOPIC`] (default true).
    pub publish_decisions: bool,
    /// Default: [`MarkersFor::Everyone`].
    pub markers: MarkersFor,
}

impl Default for ServerOptions {
    fn default() -> Self {
        Self {
            node: NodeConfig::named(DEFAULT_SERVER_NODE),
            publish_decisions: true,
            markers: MarkersFor::Everyone,
        }
    }
}

/// What the server has done so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServerCounters {
    /// Requests handed to the handler (undecodable ones included).
    pub received: u64,
    /// Of those, [`Incoming::Undecodable`].
    pub undecodable: u64,
    /// Replies whose answer was written.
    pub answered: u64,
    /// Replies whose answer could not be written (logged).
    pub send_errors: u64,
}

type Handler = dyn Fn(Incoming, Instant, Reply) + Send + Sync;

/// What the receiving thread and every [`Reply`] share. Fields drop in order: the DDS
/// entities before their node.
struct Shared {
    server: Server<IncomingRequest, msg::PlanServiceResponse>,
    decisions: Option<Publisher<msg::PlanResponse>>,
    markers: Option<Publisher<MarkerArray>>,
    markers_for: MarkersFor,
    /// Whether a marker subscriber was discovered, and when that was last looked up.
    marker_subscribers: Mutex<(bool, Option<Instant>)>,
    /// By a client's request writer (present once its participant's reply reader has
    /// been discovered): its reply reader, the only one its answers go to
    /// once known (`None`: its participant has several, answers go to every reader).
    reply_targets: Mutex<BTreeMap<GUID, Option<GUID>>>,
    received: AtomicU64,
    undecodable: AtomicU64,
    answered: AtomicU64,
    send_errors: AtomicU64,
    running: RunningNode,
}

impl Shared {
    fn node(&self) -> &Node {
        self.running.node()
    }

    /// Whether anyone subscribes to the markers (building them costs far more than
    /// publishing a decision), looked up in the discovery database at most every
    /// [`MARKER_SUBSCRIBERS_TTL`]. Not ros2-client's match count: that logs an error for a
    /// writer that has never been matched.
    fn markers_subscribed(&self) -> bool {
        let mut cached = lock(&self.marker_subscribers);
        let now = Instant::now();
        if cached
            .1
            .is_none_or(|at| now.duration_since(at) >= MARKER_SUBSCRIBERS_TTL)
        {
            let found = discovered(
                &self.running.participant,
                Endpoint::Reader,
                MARKERS_TOPIC_DDS,
                MARKERS_TYPE_DDS,
            );
            *cached = (found, Some(now));
        }
        cached.0
    }

    fn wants_markers(&self, vehicle_id: u64) -> bool {
        match self.markers_for {
            MarkersFor::Nobody => false,
            MarkersFor::Everyone => true,
            MarkersFor::Vehicle(v) => v == vehicle_id,
        }
    }

    /// Waits, at most [`REPLY_READER_WAIT`], until the reply reader of the client that sent
    /// request `id` has been discovered: the reply topic is volatile, so an answer written
    /// before the writer knows the reader is lost for good. A client's first request can
    /// outrun its reply reader's discovery (the client saw the server's endpoints first);
    /// rmw_fastrtps waits the same way (100 ms) before sending a response. Later answers
    /// to the same client find it in `reply_targets` at once.
    fn await_reply_reader(&self, id: &RmwRequestId) {
        let writer = GUID::from(id.writer_gid);
        if lock(&self.reply_targets).contains_key(&writer) {
            return;
        }
        let prefix = participant_prefix(writer);
        if !self
            .running
            .wait_until(REPLY_READER_WAIT, || self.reply_reader_discovered(prefix))
        {
            debug!(?prefix, "the client's reply reader is not discovered; answering anyway");
        }
    }

    fn reply_reader_discovered(&self, prefix: ParticipantPrefix) -> bool {
        self.running.participant.discovered_readers().iter().any(|reader| {
            participant_prefix(reader.reader_proxy.remote_reader_guid) == prefix
                && reader.subscription_topic_data.topic_name == REPLY_TOPIC_DDS
        })
    }

    /// The reply reader to write the answer to request `id` to, `None` for every matched
    /// reader. ros2-client writes an answer to every client's reply reader, and each client
    /// drops the others' (with 8 vehicles, 7 needless datagrams, wake-ups and
    /// acknowledgements per answer). The first answer to a client goes to every reader, as
    /// before, and its reply reader is looked up; later answers go to that reader alone
    /// (by then the writer has surely matched it: a reader the writer does not know yet
    /// would get nothing).
    fn reply_target(&self, id: &RmwRequestId) -> Option<GUID> {
        let writer = GUID::from(id.writer_gid);
        let mut targets = lock(&self.reply_targets);
        if let Some(target) = targets.get(&writer) {
            return *target;
        }
        let readers: Vec<GUID> = self
            .running
            .participant
            .discovered_readers()
            .iter()
            .filter(|reader| reader.subscription_topic_data.topic_name == REPLY_TOPIC_DDS)
            .map(|reader| reader.reader_proxy.remote_reader_guid)
            .collect();
        // rmw_fastrtps clients name their reply reader in the request's identity; others
        // (ros2-client) their request writer: then the participant's one reply reader.
        let target = if readers.contains(&writer) {
            Some(writer)
        } else {
            let prefix = participant_prefix(writer);
            let mut own = readers.iter().filter(|r| participant_prefix(**r) == prefix);
            match (own.next(), own.next()) {
                (Some(reader), None) => Some(*reader),
                (Some(_), Some(_)) => None,
                // Not discovered yet: look again at the next answer.
                (None, _) => return None,
            }
        };
        if targets.len() >= MAX_REPLY_TARGETS {
            targets.clear();
        }
        targets.insert(writer, target);
        None
    }

    /// Answers the client first (what it waits for), then the topics if anyone listens.
    fn answer(&self, id: RmwRequestId, request: Option<&PlanRequest>, response: PlanResponse) {
        self.await_reply_reader(&id);
        let message = msg::PlanResponse::from(&response);
        let service_response = msg::PlanServiceResponse {
            response: message.clone(),
        };
        let sent = match self.reply_target(&id) {
            Some(reader) => self.server.send_response_to_reader(id, reader, service_response),
            None => self.server.send_response(id, service_response),
        };
        match sent {
            Ok(()) => self.answered.fetch_add(1, Ordering::Relaxed),
            Err(e) => {
                warn!(
                    vehicle_id = response.vehicle_id,
                    sequence = response.sequence,
                    "cannot send the answer: {e}"
                );
                self.send_errors.fetch_add(1, Ordering::Relaxed)
            }
        };
        // A decision costs little to publish, also to nobody.
        if let Some(decisions) = &self.decisions {
            if let Err(e) = decisions.publish(message) {
                debug!("cannot publish the decision: {e}");
            }
        }
        if let (Some(markers), Some(request)) = (&self.markers, request) {
            if self.markers_subscribed() {
                if let Err(e) = markers.publish(plan_markers(request, &response, Time::now())) {
                    debug!("cannot publish the markers: {e}");
                }
            }
        }
    }
}

/// The planner's ROS 2 node. Stops (and joins its threads) on [`PlanServer::stop`] or drop.
pub struct PlanServer {
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
    waker: Waker,
    receiver: Option<JoinHandle<()>>,
}

/// How long an answer waits for its client's reply reader to be discovered.
const REPLY_READER_WAIT: Duration = Duration::from_millis(100);
/// The DDS topic of the service's replies (`rr/` + [`SERVICE_NAME`] + `Reply`).
const REPLY_TOPIC_DDS: &str = "rr/hmdp/planReply";
/// The DDS names of the published topics (`rt/` + the topic) and their types.
const DECISIONS_TOPIC_DDS: &str = "rt/hmdp/decisions";
const DECISIONS_TYPE_DDS: &str = "hmdp_msgs::msg::dds_::PlanResponse_";
const MARKERS_TOPIC_DDS: &str = "rt/hmdp/plan_markers";
const MARKERS_TYPE_DDS: &str = "visualization_msgs::msg::dds_::MarkerArray_";
/// How long a lookup of marker subscribers is trusted.
const MARKER_SUBSCRIBERS_TTL: Duration = Duration::from_millis(250);

const REQUESTS: Token = Token(0);
const WAKE: Token = Token(1);

impl PlanServer {
    /// Starts the node and serves: `handler` gets every request with its arrival time and
    /// the [`Reply`] that answers it. The handler runs on the receiving thread and must
    /// return at once; it should not panic (a panic is caught and logged, and that request
    /// stays unanswered).
    pub fn start(
        options: ServerOptions,
        handler: impl Fn(Incoming, Instant, Reply) + Send + Sync + 'static,
    ) -> Result<Self, Ros2Error> {
        let mut running = RunningNode::start(&options.node)?;
        let qos = reliable_qos(SERVICE_DEPTH);
        let mut server = running
            .node_mut()
            .create_server::<IncomingRequest, msg::PlanServiceResponse>(
                ServiceMapping::Enhanced,
                &ros_name(SERVICE_NAME)?,
                &plan_service_type_name(),
                qos.clone(),
                qos,
            )
            .map_err(|e| Ros2Error::create("the Plan service", e))?;
        let decisions = if options.publish_decisions {
            Some(publisher(
                running.node_mut(),
                DECISIONS_TOPIC,
                msg::PlanResponse::type_name(),
            )?)
        } else {
            None
        };
        let markers = if options.markers == MarkersFor::Nobody {
            None
        } else {
            Some(publisher(running.node_mut(), MARKERS_TOPIC, MarkerArray::type_name())?)
        };

        let io = |source| Ros2Error::Io {
            what: "the server's event loop",
            source,
        };
        let poll = Poll::new().map_err(io)?;
        poll.registry()
            .register(&mut server, REQUESTS, Interest::READABLE)
            .map_err(io)?;
        let waker = Waker::new(poll.registry(), WAKE).map_err(io)?;

        let shared = Arc::new(Shared {
            server,
            decisions,
            markers,
            markers_for: options.markers,
            marker_subscribers: Mutex::new((false, None)),
            reply_targets: Mutex::new(BTreeMap::new()),
            received: AtomicU64::new(0),
            undecodable: AtomicU64::new(0),
            answered: AtomicU64::new(0),
            send_errors: AtomicU64::new(0),
            running,
        });
        let stop = Arc::new(AtomicBool::new(false));
        let handler: Arc<Handler> = Arc::new(handler);
        let receiver = {
            let (shared, stop) = (Arc::clone(&shared), Arc::clone(&stop));
            thread::Builder::new()
                .name("ros2-server".to_owned())
                .spawn(move || receive_loop(poll, &shared, &stop, &*handler))
                .map_err(|source| Ros2Error::Io {
                    what: "the server thread",
                    source,
                })?
        };
        Ok(Self {
            shared,
            stop,
            waker,
            receiver: Some(receiver),
        })
    }

    /// What the server has done so far.
    pub fn counters(&self) -> ServerCounters {
        let s = &self.shared;
        ServerCounters {
            received: s.received.load(Ordering::Relaxed),
            undecodable: s.undecodable.load(Ordering::Relaxed),
            answered: s.answered.load(Ordering::Relaxed),
            send_errors: s.send_errors.load(Ordering::Relaxed),
        }
    }

    /// Waits, at most `timeout`, until a subscriber of [`DECISIONS_TOPIC`] is matched, so
    /// that the next answers reach it (the topic is volatile). Event-driven.
    pub fn wait_for_decision_subscriber(&self, timeout: Duration) -> Result<(), Ros2Error> {
        let unavailable = Ros2Error::ServiceUnavailable {
            service: DECISIONS_TOPIC,
            waited: timeout,
        };
        let Some(decisions) = &self.shared.decisions else {
            return Err(unavailable);
        };
        let (running, node) = (&self.shared.running, self.shared.node());
        // Discovered first: ros2-client's match count logs an error until the writer has
        // been matched once.
        let matched = running.wait_until(timeout, || {
            discovered(
                &running.participant,
                Endpoint::Reader,
                DECISIONS_TOPIC_DDS,
                DECISIONS_TYPE_DDS,
            )
        }) && running.wait_until(timeout, || decisions.get_subscription_count(node) > 0);
        if matched {
            Ok(())
        } else {
            Err(unavailable)
        }
    }

    /// Stops receiving and joins the threads. Replies still outstanding keep the node (and
    /// its spinner thread) alive until the last of them has answered.
    pub fn stop(self) {}

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Err(e) = self.waker.wake() {
            error!("cannot wake the server thread: {e}");
        }
        if let Some(handle) = self.receiver.take() {
            let _ = handle.join();
        }
        // The spinner is joined when the last owner of `shared` drops its node.
    }
}

impl Drop for PlanServer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The participant part (first 12 bytes) of a DDS GUID: a client's request writer and its
/// reply reader share it.
type ParticipantPrefix = [u8; 12];

/// Clients whose reply reader [`Shared::reply_target`] remembers; beyond, it starts again
/// (clients come and go over a long run).
const MAX_REPLY_TARGETS: usize = 4096;

fn participant_prefix(guid: GUID) -> ParticipantPrefix {
    let bytes = guid.to_bytes();
    let mut prefix = [0; 12];
    prefix.copy_from_slice(&bytes[..12]);
    prefix
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

fn publisher<M: serde::Serialize>(
    node: &mut Node,
    topic: &str,
    type_name: ros2_client::MessageTypeName,
) -> Result<Publisher<M>, Ros2Error> {
    let qos = reliable_qos(TOPIC_DEPTH);
    let topic = node
        .create_topic(&ros_name(topic)?, type_name, &qos)
        .map_err(|e| Ros2Error::create("a topic", e))?;
    node.create_publisher(&topic, Some(qos))
        .map_err(|e| Ros2Error::create("a publisher", e))
}

/// Consecutive read errors after which the thread stops draining until the next event.
const MAX_READ_ERRORS: u32 = 16;

fn receive_loop(mut poll: Poll, shared: &Arc<Shared>, stop: &AtomicBool, handler: &Handler) {
    let mut events = Events::with_capacity(16);
    while !stop.load(Ordering::SeqCst) {
        if let Err(e) = poll.poll(&mut events, None) {
            if e.kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            error!("the ROS 2 server's poll failed, no more requests: {e}");
            return;
        }
        if events.iter().any(|event| event.token() == REQUESTS) {
            drain(shared, handler);
        }
    }
}

/// Takes every request that has arrived (the registration is edge-triggered).
fn drain(shared: &Arc<Shared>, handler: &Handler) {
    let mut errors = 0;
    loop {
        match shared.server.receive_request() {
            Ok(Some((id, incoming))) => {
                errors = 0;
                dispatch(shared, handler, id, incoming, Instant::now());
            }
            Ok(None) => return,
            Err(e) => {
                warn!("cannot take a request: {e}");
                errors += 1;
                if errors >= MAX_READ_ERRORS {
                    return;
                }
            }
        }
    }
}

fn dispatch(shared: &Arc<Shared>, handler: &Handler, id: RmwRequestId, incoming: IncomingRequest, arrival: Instant) {
    shared.received.fetch_add(1, Ordering::Relaxed);
    let converted = match incoming {
        IncomingRequest::Decoded(message) => PlanRequest::try_from(message).map_err(|e| {
            debug!("request over capacity: {e}");
            (e.vehicle_id, e.sequence, e.rejected)
        }),
        IncomingRequest::Undecodable {
            vehicle_id,
            sequence,
            error,
        } => {
            warn!(vehicle_id, sequence, "undecodable request: {error}");
            Err((vehicle_id, sequence, Rejected::new(RejectReason::Malformed, "")))
        }
    };
    let (incoming, marker_request) = match converted {
        Ok(request) => {
            let copy = shared.wants_markers(request.vehicle_id).then(|| request.clone());
            (Incoming::Request(request), copy)
        }
        Err((vehicle_id, sequence, rejected)) => {
            shared.undecodable.fetch_add(1, Ordering::Relaxed);
            let incoming = Incoming::Undecodable {
                vehicle_id,
                sequence,
                rejected,
            };
            (incoming, None)
        }
    };
    let answering = Arc::clone(shared);
    let reply: Reply = Box::new(move |response| answering.answer(id, marker_request.as_ref(), response));
    if panic::catch_unwind(AssertUnwindSafe(|| handler(incoming, arrival, reply))).is_err() {
        error!("the request handler panicked; that request stays unanswered");
    }
}
