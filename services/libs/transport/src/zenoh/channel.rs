//! The vehicle's side: [`ZenohChannel`], one request at a time, to the vehicle's planner
//! instance with one retry on the next, or to the plain key when no instance is known.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use ::zenoh::pubsub::Subscriber;
use ::zenoh::query::{ConsolidationMode, Querier, QueryTarget, Reply};
use ::zenoh::{Session, Wait};
use protocol::{PlanRequest, PlanResponse, ResponseVerifier, WireFormat, ZENOH_PLAN_KEY};

use super::instances::{follow, instance_plan_key, Instances};
use super::{check_request_size, encoding, Failover, ZenohTarget};
use crate::{await_ready, Answer, ChannelError, PlanChannel};

/// Requests as Zenoh queries (bincode payloads). With planner instances in sight (their
/// liveliness tokens on `hmdp/planner/alive/*`), a request goes to its vehicle's instance,
/// `hmdp/planner/plan/<instance>`, chosen by rendezvous hashing of the vehicle id, and once
/// more to the next instance when no valid answer came within [`Failover::retry_after`];
/// without any, to [`ZENOH_PLAN_KEY`] as before. Every reply is read (no consolidation):
/// with a key, a forged reply that arrives first does not hide the planner's.
pub struct ZenohChannel {
    session: Session,
    querier: Querier<'static>,
    verifier: Option<ResponseVerifier>,
    instances: Instances,
    /// Keeps `instances` up to date; undeclared on drop.
    _alive: Subscriber<()>,
    failover: Failover,
}

/// What the reply callbacks of an exchange's queries tell it.
enum Event {
    Reply {
        attempt: usize,
        bytes: Vec<u8>,
        at: Instant,
    },
    /// The query of `attempt` is over: every queryable answered, or it timed out.
    Final(usize),
}

/// Held by a query's reply callback: Zenoh drops the callback when the query is over, and
/// the drop tells the exchange.
struct Sink {
    attempt: usize,
    tx: mpsc::Sender<Event>,
}

impl Drop for Sink {
    fn drop(&mut self) {
        let _ = self.tx.send(Event::Final(self.attempt));
    }
}

impl ZenohChannel {
    /// Opens a session to `target` (retrying until `ready_timeout`), declares a querier whose
    /// queries end after `query_timeout`, follows the planner instances' liveliness tokens,
    /// and waits until a planner answers a probe (the empty query, which comes back rejected).
    pub fn connect(
        target: &ZenohTarget,
        ready_timeout: Duration,
        query_timeout: Duration,
    ) -> Result<Self, ChannelError> {
        let since = Instant::now();
        let at = || format!("at {}", target.describe());
        target.check_security(&target.config()?)?;
        let session = loop {
            match ::zenoh::open(target.config()?).wait() {
                Ok(s) => break s,
                Err(source) if since.elapsed() >= ready_timeout => {
                    return Err(ChannelError::Zenoh {
                        what: format!("cannot reach the planner {}", at()),
                        source,
                    })
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let querier = session
            .declare_querier(ZENOH_PLAN_KEY)
            .timeout(query_timeout)
            .consolidation(ConsolidationMode::None)
            .wait()
            .map_err(|source| ChannelError::Zenoh {
                what: "declaring the querier".into(),
                source,
            })?;
        let (instances, alive) = follow(&session).map_err(|source| ChannelError::Zenoh {
            what: "following the planner instances".into(),
            source,
        })?;
        let channel = Self {
            session,
            querier,
            verifier: target.verifier.clone(),
            instances,
            _alive: alive,
            failover: target.failover,
        };
        // Say why when only refused answers came: a planner without the key is not absent.
        let refused = std::cell::Cell::new(None);
        let at_why = || match refused.get() {
            Some(e) => format!("{} with a verified answer ({e})", at()),
            None => at(),
        };
        await_ready(since, ready_timeout, Duration::from_millis(100), at_why, || {
            let replies = channel.ask_raw(&[], WireFormat::Bincode, Duration::from_millis(500));
            if channel.verifier.is_none() {
                return Ok(!replies.is_empty());
            }
            let mut ready = false;
            for (bytes, _) in &replies {
                match channel.verified(bytes) {
                    Ok(_) => ready = true,
                    Err(Some(e)) => refused.set(Some(e)),
                    Err(None) => {}
                }
            }
            Ok(ready)
        })?;
        Ok(channel)
    }

    /// A reply decoded and, with a key, verified. `Err(None)`: it does not decode.
    fn verified(&self, bytes: &[u8]) -> Result<PlanResponse, Option<protocol::VerifyError>> {
        let response = protocol::decode_bincode::<PlanResponse>(bytes).map_err(|e| {
            tracing::warn!("undecodable answer: {e}");
            None
        })?;
        match &self.verifier {
            Some(verifier) => verifier.verify(&response).map(|()| response).map_err(Some),
            None => Ok(response),
        }
    }

    /// Every reply payload to one query of `payload` in `format` on [`ZENOH_PLAN_KEY`],
    /// until every queryable has answered, the querier's timeout, or `wait` (after the first
    /// reply).
    pub fn ask_raw(&self, payload: &[u8], format: WireFormat, wait: Duration) -> Vec<(Vec<u8>, Instant)> {
        let deadline = Instant::now() + wait;
        let mut replies_seen = Vec::new();
        let Ok(replies) = self
            .querier
            .get()
            .payload(payload.to_vec())
            .encoding(encoding(format))
            .wait()
        else {
            return replies_seen;
        };
        while let Ok(Some(reply)) = replies.recv_deadline(deadline) {
            if let Ok(sample) = reply.result() {
                replies_seen.push((sample.payload().to_bytes().into_owned(), Instant::now()));
            }
            if deadline <= Instant::now() {
                break;
            }
        }
        replies_seen
    }

    /// Sends `payload` (bincode) as one query on [`ZENOH_PLAN_KEY`] and returns at once;
    /// `on_reply` gets every reply's payload. For load generators that do not wait for their
    /// answers (`sim_client load --flood-sessions`).
    pub fn send_without_waiting(
        &self,
        payload: Vec<u8>,
        on_reply: impl Fn(Vec<u8>) + Send + Sync + 'static,
    ) -> Result<(), ChannelError> {
        check_request_size(payload.len())?;
        self.querier
            .get()
            .payload(payload)
            .encoding(encoding(WireFormat::Bincode))
            .callback(move |reply: Reply| {
                if let Ok(sample) = reply.result() {
                    on_reply(sample.payload().to_bytes().into_owned());
                }
            })
            .wait()
            .map_err(|source| ChannelError::Zenoh {
                what: "sending a query".into(),
                source,
            })
    }

    /// The planner instances whose liveliness tokens this channel sees, by name.
    pub fn instances(&self) -> Vec<String> {
        self.instances.live()
    }

    /// The Zenoh session (to declare more entities on it).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// Sends `payload` as query `attempt` to instance `instance` (the plain key if `None`);
    /// its replies and its end arrive on `tx`.
    fn send(
        &self,
        attempt: usize,
        instance: Option<&str>,
        payload: &[u8],
        timeout: Duration,
        tx: &mpsc::Sender<Event>,
    ) {
        let sink = Sink {
            attempt,
            tx: tx.clone(),
        };
        let callback = move |reply: Reply| {
            if let Ok(sample) = reply.result() {
                let bytes = sample.payload().to_bytes().into_owned();
                let _ = sink.tx.send(Event::Reply {
                    attempt: sink.attempt,
                    bytes,
                    at: Instant::now(),
                });
            }
        };
        let format = encoding(WireFormat::Bincode);
        let sent = match instance {
            None => self
                .querier
                .get()
                .payload(payload.to_vec())
                .encoding(format)
                .callback(callback)
                .wait(),
            // Target `All`: a forged queryable on the instance's key does not take the query
            // away from the instance (with a key its answers are refused).
            Some(id) => self
                .session
                .get(instance_plan_key(id))
                .payload(payload.to_vec())
                .encoding(format)
                .target(QueryTarget::All)
                .consolidation(ConsolidationMode::None)
                .timeout(timeout)
                .callback(callback)
                .wait(),
        };
        // A query that could not be sent has dropped its callback: it ends at once.
        if let Err(e) = sent {
            tracing::warn!(instance = instance.unwrap_or("any"), "query not sent: {e}");
        }
    }
}

impl PlanChannel for ZenohChannel {
    /// The first valid answer for this request (its vehicle id and sequence) wins; later
    /// answers of the same query are counted as extra responses, those of the other query
    /// (after a retry) are discarded, answers for another request are counted as mismatched.
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, ChannelError> {
        let start = Instant::now();
        let deadline = start + wait;
        let retry_at = start + self.failover.retry_after;
        let payload = protocol::encode_bincode(&request);
        check_request_size(payload.len())?;
        let expected = (request.vehicle_id, request.sequence);
        let order = self.instances.order(request.vehicle_id, start);
        let (tx, rx) = mpsc::channel();
        self.send(0, order.first().map(String::as_str), &payload, wait, &tx);
        let (mut sent, mut ended) = (1, 0);
        let mut answer = Answer::default();
        let mut answered_by = None;
        loop {
            let may_retry = answered_by.is_none() && sent < order.len().min(2);
            let wake = if may_retry { retry_at.min(deadline) } else { deadline };
            let event = rx.recv_timeout(wake.saturating_duration_since(Instant::now())).ok();
            let retry_now = match event {
                Some(Event::Reply { attempt, bytes, at }) => {
                    match self.verified(&bytes) {
                        // Another request's answer (a stray or replayed reply on this key):
                        // never taken, counted, as the iceoryx2 client does.
                        Ok(response) if (response.vehicle_id, response.sequence) != expected => {
                            tracing::warn!(
                                expected = ?expected,
                                got = ?(response.vehicle_id, response.sequence),
                                "an answer for another request: ignored"
                            );
                            answer.mismatched += 1;
                        }
                        Ok(response) if answered_by.is_none() => {
                            answer.response = Some(response);
                            answer.answered_at = Some(at);
                            answered_by = Some(attempt);
                        }
                        Ok(_) if answered_by == Some(attempt) => answer.extra_responses += 1,
                        Ok(_) => {}
                        Err(Some(e)) => {
                            tracing::warn!(sequence = request.sequence, "answer refused: {e}");
                            answer.refused.push(e);
                        }
                        Err(None) => {}
                    }
                    false
                }
                Some(Event::Final(attempt)) => {
                    ended += 1;
                    if answered_by == Some(attempt) || (ended == sent && !may_retry) {
                        break;
                    }
                    // The instance's query ended without a valid answer (it went away, or
                    // only forgeries came): no reason to wait for the retry time.
                    may_retry && ended == sent
                }
                None if Instant::now() >= deadline => break,
                None => may_retry,
            };
            if retry_now {
                let (silent, next) = (&order[0], &order[1]);
                tracing::warn!(
                    vehicle = request.vehicle_id,
                    sequence = request.sequence,
                    "planner instance {silent} gave no answer in {:?}: asking {next}",
                    start.elapsed()
                );
                self.instances
                    .suspect(silent, Instant::now() + self.failover.suspect_for);
                self.send(
                    1,
                    Some(next),
                    &payload,
                    deadline.saturating_duration_since(Instant::now()),
                    &tx,
                );
                sent += 1;
                answer.retries += 1;
            }
        }
        Ok(answer)
    }

    fn name(&self) -> &'static str {
        "zenoh"
    }
}
