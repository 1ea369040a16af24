//! Plain-key queries shared out among the instances. A client that only knows
//! `hmdp/planner/plan` (any client written from docs/protocol.md) reaches the one instance
//! its router picks: Zenoh routes a query with the default target to one complete
//! queryable, and always the same one. That instance serves the vehicles that rendezvous
//! hashing gives it and forwards every other request to its own instance's key,
//! `hmdp/planner/plan/<id>`, relaying the answer. When that instance gives no valid answer
//! within the retry time (or its query ends without one), the request is served here and
//! the silent instance is suspected, as the Rust and Python vehicles fail over
//! (docs/deploy.md, "Scaling out").

use std::sync::Arc;
use std::time::{Duration, Instant};

use protocol::{PlanResponse, ResponseVerifier, WireFormat, DEFAULT_DEADLINE};
use transport::zenoh::instances::{follow, instance_plan_key, Instances};
use transport::zenoh::{encoding, format_of, Failover};
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, Query, QueryTarget};
use zenoh::sample::Sample;
use zenoh::Session;

use super::{failed, ZenohFrontError};
use crate::Stats;

/// Serves a query on this instance (the front end's ordinary path).
pub(super) type ServeHere = Arc<dyn Fn(Query, Vec<u8>, WireFormat, Instant) + Send + Sync>;

/// How long a forwarded query may run: the longest deadline a planner applies, and time for
/// a watchdog answer given at that deadline to come back.
const FORWARD_TIMEOUT: Duration = DEFAULT_DEADLINE.saturating_add(Duration::from_millis(100));

/// Decides, for each plain-key query, whether this instance serves it or forwards it.
pub(super) struct Forwarder {
    session: Session,
    own: String,
    instances: Instances,
    /// Keeps `instances` up to date; undeclared on drop.
    _alive: Subscriber<()>,
    /// This instance's own key: with signing, the other instances' answers must verify
    /// with it (every instance of a deployment signs with the key the vehicles hold).
    verifier: Option<ResponseVerifier>,
    failover: Failover,
    runtime: tokio::runtime::Handle,
    serve_here: ServeHere,
    stats: Arc<Stats>,
}

impl Forwarder {
    /// Follows the instances' liveliness tokens on `session`; `own` is this instance's id.
    pub(super) fn start(
        session: &Session,
        own: String,
        verifier: Option<ResponseVerifier>,
        serve_here: ServeHere,
        stats: Arc<Stats>,
    ) -> Result<Arc<Self>, ZenohFrontError> {
        let (instances, alive) = follow(session).map_err(failed("following the planner instances"))?;
        Ok(Arc::new(Self {
            session: session.clone(),
            own,
            instances,
            _alive: alive,
            verifier,
            failover: Failover::default(),
            runtime: tokio::runtime::Handle::current(),
            serve_here,
            stats,
        }))
    }

    /// The instance that should serve `vehicle` at `now`, if not this one.
    fn peer_for(&self, vehicle: u64, now: Instant) -> Option<String> {
        self.instances
            .order(vehicle, now)
            .into_iter()
            .next()
            .filter(|first| *first != self.own)
    }

    /// Serves a plain-key query here or forwards it. Called on Zenoh's threads: never
    /// blocks (a forward runs as a task of the front end's runtime).
    pub(super) fn dispatch(self: &Arc<Self>, query: Query, bytes: Vec<u8>, format: WireFormat, arrival: Instant) {
        let ids = format.peek_ids(&bytes);
        // The empty query is a readiness probe: it asks whether *a* planner serves.
        let peer = (!bytes.is_empty()).then(|| self.peer_for(ids.0, arrival)).flatten();
        match peer {
            None => (self.serve_here)(query, bytes, format, arrival),
            Some(peer) => {
                let this = Arc::clone(self);
                self.runtime
                    .spawn(async move { this.forward(peer, query, bytes, format, arrival, ids).await });
            }
        }
    }

    /// Sends the request to `peer`'s key and relays its first valid answer; without one by
    /// the retry time, serves it here.
    async fn forward(
        self: Arc<Self>,
        peer: String,
        query: Query,
        bytes: Vec<u8>,
        format: WireFormat,
        arrival: Instant,
        ids: (u64, u64),
    ) {
        let retry_at = tokio::time::Instant::from_std(arrival + self.failover.retry_after);
        // Target `All` and no consolidation: the instance's answer cannot be hidden by a
        // forged queryable on its key (with signing, a forgery does not verify). Drop: never
        // block this planner's sending on a congested link (the replies inherit it).
        let sent = self
            .session
            .get(instance_plan_key(&peer))
            .payload(bytes.clone())
            .encoding(encoding(format))
            .target(QueryTarget::All)
            .consolidation(ConsolidationMode::None)
            .congestion_control(CongestionControl::Drop)
            .timeout(FORWARD_TIMEOUT)
            .await;
        let mut answer = None;
        match sent {
            Ok(replies) => {
                // Ends at the retry time, or when the query is over (every queryable answered).
                while let Ok(Ok(reply)) = tokio::time::timeout_at(retry_at, replies.recv_async()).await {
                    if let Ok(sample) = reply.result() {
                        if self.valid(sample, ids) {
                            answer = Some(sample.clone());
                            break;
                        }
                    }
                }
            }
            Err(e) => tracing::warn!(instance = %peer, "forward not sent: {e}"),
        }
        match answer {
            Some(sample) => {
                self.stats.count_forward(false);
                let key = query.key_expr().clone();
                let relayed = query
                    .reply(key, sample.payload().clone())
                    .encoding(sample.encoding().clone())
                    .await;
                if let Err(e) = relayed {
                    tracing::warn!("relaying the answer of {peer} failed: {e}");
                }
            }
            None => {
                self.stats.count_forward(true);
                self.instances
                    .suspect(&peer, Instant::now() + self.failover.suspect_for);
                tracing::warn!(
                    vehicle = ids.0,
                    sequence = ids.1,
                    "planner instance {peer} gave no answer in {:?}: serving the request here",
                    arrival.elapsed()
                );
                (self.serve_here)(query, bytes, format, arrival);
            }
        }
    }

    /// Whether a reply to a forward is the answer to relay: it decodes, answers this very
    /// request, and with signing verifies.
    fn valid(&self, sample: &Sample, ids: (u64, u64)) -> bool {
        let format = format_of(Some(sample.encoding()));
        let Ok(response) = format.decode::<PlanResponse>(&sample.payload().to_bytes()) else {
            return false;
        };
        if (response.vehicle_id, response.sequence) != ids {
            return false;
        }
        match &self.verifier {
            Some(verifier) => verifier.verify(&response).is_ok(),
            None => true,
        }
    }
}
