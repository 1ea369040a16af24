//! Names shared by every process: transport services, key expressions, encodings.

/// iceoryx2 request-response service: [`PlanRequest`](crate::PlanRequest) in,
/// [`PlanResponse`](crate::PlanResponse) out.
pub const ICEORYX2_PLAN_SERVICE: &str = "hmdp/planner/plan";
/// iceoryx2 event service a client notifies after sending a request: it wakes the planner
/// (iceoryx2 request-response has no blocking receive, events pair with it).
pub const ICEORYX2_PLAN_REQUEST_EVENT_SERVICE: &str = "hmdp/planner/plan/requests";
/// iceoryx2 event service the planner notifies after sending a response: it wakes the
/// waiting clients, which each look whether the answer is theirs.
pub const ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE: &str = "hmdp/planner/plan/responses";

/// Zenoh key expression of the planner's queryable: the query payload is a
/// [`PlanRequest`](crate::PlanRequest), the reply a [`PlanResponse`](crate::PlanResponse).
pub const ZENOH_PLAN_KEY: &str = "hmdp/planner/plan";
/// Zenoh key expression of every planner instance's own queryable,
/// `hmdp/planner/plan/<instance>`: the same payloads as [`ZENOH_PLAN_KEY`], sent there by
/// a client that picks an instance (scale-out and failover, docs/deploy.md).
pub const ZENOH_PLAN_INSTANCE_KEYS: &str = "hmdp/planner/plan/*";
/// Zenoh liveliness tokens of the serving planner instances, `hmdp/planner/alive/<instance>`.
pub const ZENOH_ALIVE_KEYS: &str = "hmdp/planner/alive/*";
/// Zenoh key expression on which the planner publishes its statistics.
pub const ZENOH_STATS_KEY: &str = "hmdp/planner/stats";

/// Encoding (Zenoh encoding / HTTP content type) of the bincode form.
pub const ENCODING_BINCODE: &str = "application/x-hmdp-bincode";
/// Encoding of the JSON form.
pub const ENCODING_JSON: &str = "application/json";
