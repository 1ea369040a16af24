//! [`PlanClient`]: a vehicle's (or the simulator's) side of the planner's ROS 2 service,
//! with a blocking API; and [`DecisionSubscriber`] for the answers the planner publishes.
//!
//! One `PlanClient` serves any number of threads at once: each [`PlanClient::exchange`]
//! registers its request's RMW id before the request leaves, then waits for the answer to
//! that id. The client has no thread of its own: one waiting exchange at a time (the
//! leader) sleeps in the mio poll on the reply reader and routes every answer it takes to
//! the exchange waiting for its id; the others sleep on a condition variable until their
//! answer is routed or the leader leaves, and one of them then leads. An exchange alone
//! (a vehicle's usual case) is thus woken by RustDDS's event loop directly, one thread
//! handoff fewer than a reply thread passing the answer on. A client may read answers
//! to other clients on the one reply topic (the planner's first answer to each client goes
//! to every reply reader); those, and late answers to requests that have timed out, are
//! dropped there: an exchange only ever returns the
//! answer to its own request, and checks that it echoes the request's vehicle id and
//! sequence.

use std::collections::BTreeMap;
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use protocol::{PlanRequest, PlanResponse};
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::{Client, RmwRequestId, ServiceMapping, Subscription};
use tracing::{debug, warn};

use crate::incoming::IncomingResponse;
use crate::msg::{self, plan_service_type_name};
use crate::node::{discovered, reliable_qos, ros_name, Endpoint, NodeConfig, RunningNode, SERVICE_DEPTH, TOPIC_DEPTH};
use crate::{Ros2Error, DECISIONS_TOPIC, SERVICE_NAME};

/// How to start a [`PlanClient`] or a [`DecisionSubscriber`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClientOptions {
    /// Default: node `hmdp_vehicle_<pid>` in `/`, domain and discovery from the environment.
    pub node: NodeConfig,
}

impl Default for ClientOptions {
    fn default() -> Self {
        Self {
            node: NodeConfig::named(format!("hmdp_vehicle_{}", std::process::id())),
        }
    }
}

/// An exchange waiting for its answer.
struct Waiter {
    ids: (u64, u64),
    answer: Option<IncomingResponse>,
}

/// The exchanges waiting, and whether one of them is polling the reply reader.
#[derive(Default)]
struct Waiting {
    by_id: BTreeMap<RmwRequestId, Waiter>,
    leader: bool,
}

/// A blocking client of the planner's ROS 2 service. Fields drop in order: the DDS
/// entities before their node.
pub struct PlanClient {
    client: Client<msg::PlanServiceRequest, IncomingResponse>,
    waiting: Mutex<Waiting>,
    /// Notified when an answer is routed to a waiting exchange or the leader leaves.
    turn: Condvar,
    /// The reply reader's poll; only the leader locks it.
    poll: Mutex<(Poll, Events)>,
    running: RunningNode,
}

const REPLIES: Token = Token(0);

/// The service's DDS topics and types (`rq/` and `rr/` + the service name, the
/// `srv::dds_` types), as ros2-client names them.
const REQUEST_TOPIC_DDS: &str = "rq/hmdp/planRequest";
const REQUEST_TYPE_DDS: &str = "hmdp_msgs::srv::dds_::Plan_Request_";
const REPLY_TOPIC_DDS: &str = "rr/hmdp/planReply";
const REPLY_TYPE_DDS: &str = "hmdp_msgs::srv::dds_::Plan_Response_";

/// How long one readiness probe of [`PlanClient::wait_for_service`] waits for its answer
/// before the next is sent.
const PROBE_WAIT: Duration = Duration::from_millis(250);

impl PlanClient {
    /// Creates the node and the service client; it does not wait for a server.
    pub fn new(options: ClientOptions) -> Result<Self, Ros2Error> {
        let mut running = RunningNode::start(&options.node)?;
        let qos = reliable_qos(SERVICE_DEPTH);
        let mut client = running
            .node_mut()
            .create_client::<msg::PlanServiceRequest, IncomingResponse>(
                ServiceMapping::Enhanced,
                &ros_name(SERVICE_NAME)?,
                &plan_service_type_name(),
                qos.clone(),
                qos,
            )
            .map_err(|e| Ros2Error::create("the Plan service client", e))?;
        let io = |source| Ros2Error::Io {
            what: "the client's event loop",
            source,
        };
        let poll = Poll::new().map_err(io)?;
        poll.registry()
            .register(&mut client, REPLIES, Interest::READABLE)
            .map_err(io)?;
        Ok(Self {
            client,
            waiting: Mutex::new(Waiting::default()),
            turn: Condvar::new(),
            poll: Mutex::new((poll, Events::with_capacity(16))),
            running,
        })
    }

    /// Waits, at most `timeout`, until a server's request reader and reply writer are
    /// discovered (event-driven: discovery wakes it) and the server has answered a
    /// readiness probe ([`PlanRequest::probe`], which the planner
    /// counts apart from requests). The probe proves that the server also knows this
    /// client's reply reader: a request sent before that would get an answer nobody
    /// receives (the reply topic is volatile). Probes are sent every 250 ms until one is
    /// answered.
    pub fn wait_for_service(&self, timeout: Duration) -> Result<(), Ros2Error> {
        let deadline = Instant::now() + timeout;
        let unavailable = || Ros2Error::ServiceUnavailable {
            service: SERVICE_NAME,
            waited: timeout,
        };
        let running = &self.running;
        let matched = running.wait_until(timeout, || {
            let p = &running.participant;
            discovered(p, Endpoint::Reader, REQUEST_TOPIC_DDS, REQUEST_TYPE_DDS)
                && discovered(p, Endpoint::Writer, REPLY_TOPIC_DDS, REPLY_TYPE_DDS)
        });
        if !matched {
            return Err(unavailable());
        }
        debug!("a server of {SERVICE_NAME} is matched; probing it");
        let probe_id = u64::from(std::process::id());
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Err(unavailable());
            }
            if self
                .exchange(&PlanRequest::probe(probe_id), remaining.min(PROBE_WAIT))?
                .is_some()
            {
                return Ok(());
            }
            debug!("readiness probe unanswered");
        }
    }

    /// Sends `request` and waits at most `wait` for its answer: `Ok(None)` when none came in
    /// time. Safe to call from many threads at once.
    pub fn exchange(&self, request: &PlanRequest, wait: Duration) -> Result<Option<PlanResponse>, Ros2Error> {
        self.exchange_msg(msg::PlanRequest::from(request), wait)
    }

    /// [`PlanClient::exchange`] for a request already in its ROS form, sent as it is (the
    /// server answers one the protocol cannot hold with a typed rejection).
    pub fn exchange_msg(&self, request: msg::PlanRequest, wait: Duration) -> Result<Option<PlanResponse>, Ros2Error> {
        let deadline = Instant::now() + wait;
        let ids = (request.vehicle_id, request.sequence);
        let mut waiting = lock(&self.waiting);
        // Registered before it leaves, under the lock answers are routed with, so that even
        // an immediate answer finds its waiter.
        let id = self
            .client
            .send_request(msg::PlanServiceRequest { request })
            .map_err(|e| Ros2Error::Send(e.to_string()))?;
        waiting.by_id.insert(id, Waiter { ids, answer: None });
        let answer = loop {
            if let Some(answer) = waiting.by_id.get_mut(&id).and_then(|w| w.answer.take()) {
                break Some(answer);
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                break None;
            }
            if waiting.leader {
                waiting = self
                    .turn
                    .wait_timeout(waiting, remaining)
                    .unwrap_or_else(PoisonError::into_inner)
                    .0;
                continue;
            }
            waiting.leader = true;
            drop(waiting);
            let led = self.lead(id, deadline);
            waiting = lock(&self.waiting);
            waiting.leader = false;
            // Other exchanges may be waiting for their answers: one of them leads now.
            if waiting.by_id.len() > 1 {
                self.turn.notify_all();
            }
            if let Err(e) = led {
                waiting.by_id.remove(&id);
                return Err(e);
            }
        };
        waiting.by_id.remove(&id);
        drop(waiting);
        match answer {
            Some(IncomingResponse::Decoded(message)) => Ok(Some(PlanResponse::try_from(message)?)),
            Some(IncomingResponse::Undecodable(error)) => Err(Ros2Error::UndecodableResponse(error)),
            None => Ok(None),
        }
    }

    /// As the leader: takes and routes answers until `mine` has its answer or `deadline`
    /// passes. Answers that arrived while nobody polled are taken first.
    fn lead(&self, mine: RmwRequestId, deadline: Instant) -> Result<(), Ros2Error> {
        let mut guard = lock(&self.poll);
        let (poll, events) = &mut *guard;
        loop {
            if self.drain_replies(mine) {
                return Ok(());
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(());
            }
            if let Err(e) = poll.poll(events, Some(remaining)) {
                if e.kind() != std::io::ErrorKind::Interrupted {
                    warn!("the ROS 2 client's poll failed: {e}");
                    return Err(Ros2Error::Poll(e));
                }
            }
        }
    }

    /// Takes every answer that has arrived and routes each to its exchange; whether `mine`
    /// got its answer.
    fn drain_replies(&self, mine: RmwRequestId) -> bool {
        let mut errors = 0;
        let mut answered = false;
        loop {
            match self.client.receive_response() {
                Ok(Some((id, response))) => answered |= self.route(id, response, mine),
                Ok(None) => return answered,
                Err(e) => {
                    warn!("cannot take an answer: {e}");
                    errors += 1;
                    if errors >= 16 {
                        return answered;
                    }
                }
            }
        }
    }

    /// Hands `response` to the exchange waiting for `id`; whether that is `mine`.
    fn route(&self, id: RmwRequestId, response: IncomingResponse, mine: RmwRequestId) -> bool {
        let mut waiting = lock(&self.waiting);
        let Some(waiter) = waiting.by_id.get_mut(&id) else {
            // Another client's answer, or one that came after its exchange gave up.
            return false;
        };
        if let IncomingResponse::Decoded(message) = &response {
            if (message.vehicle_id, message.sequence) != waiter.ids {
                warn!(
                    expected = ?waiter.ids,
                    got = ?(message.vehicle_id, message.sequence),
                    "an answer with this request's id echoes another request; ignored"
                );
                return false;
            }
        }
        waiter.answer = Some(response);
        if id == mine {
            return true;
        }
        self.turn.notify_all();
        false
    }
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Receives the answers the planner publishes on [`DECISIONS_TOPIC`] (every vehicle's),
/// blocking. Has its own node.
pub struct DecisionSubscriber {
    poll: Mutex<(Poll, Events)>,
    subscription: Subscription<msg::PlanResponse>,
    // Last: the subscription drops before its node.
    running: RunningNode,
}

impl DecisionSubscriber {
    /// Subscribes (reliable, volatile, keep-last 10).
    pub fn new(options: ClientOptions) -> Result<Self, Ros2Error> {
        let mut running = RunningNode::start(&options.node)?;
        let qos = reliable_qos(TOPIC_DEPTH);
        let topic = running
            .node_mut()
            .create_topic(&ros_name(DECISIONS_TOPIC)?, msg::PlanResponse::type_name(), &qos)
            .map_err(|e| Ros2Error::create("a topic", e))?;
        let mut subscription = running
            .node_mut()
            .create_subscription::<msg::PlanResponse>(&topic, Some(qos))
            .map_err(|e| Ros2Error::create("a subscription", e))?;
        let io = |source| Ros2Error::Io {
            what: "the subscriber's event loop",
            source,
        };
        let poll = Poll::new().map_err(io)?;
        poll.registry()
            .register(&mut subscription, Token(0), Interest::READABLE)
            .map_err(io)?;
        Ok(Self {
            poll: Mutex::new((poll, Events::with_capacity(4))),
            subscription,
            running,
        })
    }

    /// Waits, at most `timeout`, until a publisher (the planner) is matched. Event-driven.
    pub fn wait_for_publisher(&self, timeout: Duration) -> Result<(), Ros2Error> {
        let node = self.running.node();
        if self
            .running
            .wait_until(timeout, || self.subscription.get_publisher_count(node) > 0)
        {
            Ok(())
        } else {
            Err(Ros2Error::ServiceUnavailable {
                service: DECISIONS_TOPIC,
                waited: timeout,
            })
        }
    }

    /// The next published answer, or `Ok(None)` when none came within `wait`.
    pub fn recv_timeout(&self, wait: Duration) -> Result<Option<PlanResponse>, Ros2Error> {
        let deadline = Instant::now() + wait;
        let mut guard = lock(&self.poll);
        let (poll, events) = &mut *guard;
        loop {
            match self.subscription.take() {
                Ok(Some((message, _info))) => return Ok(Some(PlanResponse::try_from(message)?)),
                Ok(None) => {}
                Err(e) => debug!("cannot take a decision: {e}"),
            }
            let remaining = deadline.saturating_duration_since(Instant::now());
            if remaining.is_zero() {
                return Ok(None);
            }
            if let Err(e) = poll.poll(events, Some(remaining)) {
                if e.kind() != std::io::ErrorKind::Interrupted {
                    return Err(Ros2Error::Io {
                        what: "the subscriber's event loop",
                        source: e,
                    });
                }
            }
        }
    }
}
