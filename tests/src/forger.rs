//! A forged planner for the tests of signed answers.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use protocol::{Layer, OutcomeRef, PlanResponse, ResponseSigner, SetPoint, ZENOH_PLAN_KEY};
use transport::zenoh::{encoding, format_of};
use zenoh::query::Query;
use zenoh::Wait;

/// The forger's set-point: no planner commands this, so a vehicle that took a forgery shows.
pub const FORGED_ACCEL: f64 = 9.75;

/// The forger: a Zenoh client session of the planner's network answering every plan query
/// at once with a nominal-looking decision for the asking vehicle, alternately unsigned and
/// signed with its own key, for the request's sequence minus `replay` (0: for the very
/// request; 1: an old answer replayed). Counts what it sent.
pub struct Forger {
    _session: zenoh::Session,
    _queryable: zenoh::query::Queryable<()>,
    /// Forged answers sent.
    pub sent: Arc<AtomicU64>,
}

impl Forger {
    /// Connects to `endpoint` and answers from then on.
    pub fn start(endpoint: &str, replay: u64) -> Self {
        let config = transport::zenoh::client_config(endpoint).unwrap();
        let session = zenoh::open(config).wait().expect("forger session");
        let own_key = ResponseSigner::from_seed(&[0x66; 32]);
        let sent = Arc::new(AtomicU64::new(0));
        let counter = Arc::clone(&sent);
        let queryable = session
            .declare_queryable(format!("{ZENOH_PLAN_KEY}/**"))
            .complete(true)
            .callback(move |query: Query| {
                let format = format_of(query.encoding());
                let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
                let (vehicle_id, sequence) = format.peek_ids(&bytes);
                let mut decided = protocol::Decided::default();
                decided.set_layer(Layer::Nominal);
                decided.next_maneuver = protocol::Maneuver { lane: 1, beta: 1 };
                decided.setpoint = SetPoint {
                    accel_mps2: FORGED_ACCEL,
                    target_speed_mps: 40.0,
                };
                let sequence = sequence.wrapping_sub(replay);
                let mut forged = PlanResponse::decided(vehicle_id, sequence, decided, 900, 10);
                let n = counter.fetch_add(1, Ordering::SeqCst);
                if n % 2 == 1 {
                    own_key.sign(&mut forged);
                }
                let key = query.key_expr().clone();
                let _ = query
                    .reply(key, format.encode(&forged))
                    .encoding(encoding(format))
                    .wait();
            })
            .wait()
            .expect("forged queryable");
        Self {
            _session: session,
            _queryable: queryable,
            sent,
        }
    }
}

/// Whether `response` is one of the forger's.
pub fn forged(response: &PlanResponse) -> bool {
    matches!(response.outcome.get(), Ok(OutcomeRef::Decided(d)) if d.setpoint.accel_mps2 == FORGED_ACCEL)
}
