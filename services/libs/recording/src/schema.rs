//! JSON Schemas of the recorded message types, written by hand to match the protocol's serde
//! JSON form (docs/protocol.md, "JSON form"): Foxglove reads them to name the fields.

use serde_json::{json, Value};

fn number() -> Value {
    json!({ "type": "number" })
}

fn integer() -> Value {
    json!({ "type": "integer" })
}

/// An object with these properties, all required unless listed in `optional`.
fn object(properties: &[(&str, Value)], optional: &[&str]) -> Value {
    let required: Vec<&str> = properties
        .iter()
        .map(|(name, _)| *name)
        .filter(|name| !optional.contains(name))
        .collect();
    let properties: serde_json::Map<String, Value> = properties
        .iter()
        .map(|(name, v)| ((*name).to_owned(), v.clone()))
        .collect();
    json!({ "type": "object", "properties": properties, "required": required })
}

fn array(items: Value) -> Value {
    json!({ "type": "array", "items": items })
}

fn maneuver() -> Value {
    object(&[("lane", integer()), ("beta", integer())], &[])
}

fn action() -> Value {
    object(&[("lateral", integer()), ("longitudinal", integer())], &[])
}

fn memory() -> Value {
    let corrective = object(
        &[("sv_id", integer()), ("release_m", number()), ("trigger_m", number())],
        &[],
    );
    object(
        &[("corrective", array(corrective)), ("previous_plan", array(action()))],
        &[],
    )
}

/// Wraps a root schema with its title.
fn titled(title: &str, mut schema: Value) -> Value {
    if let Value::Object(map) = &mut schema {
        map.insert("$schema".into(), json!("https://json-schema.org/draft/2020-12/schema"));
        map.insert("title".into(), json!(title));
    }
    schema
}

/// `protocol::PlanRequest`.
pub fn plan_request() -> Value {
    let road = object(
        &[
            ("lanes", integer()),
            ("lane_width_m", number()),
            ("speed_limit_mps", number()),
        ],
        &[],
    );
    let ego = object(
        &[
            ("x_m", number()),
            ("y_m", number()),
            ("v_mps", number()),
            ("desired_speed_mps", number()),
            ("maneuver", maneuver()),
        ],
        &[],
    );
    let sv = object(
        &[
            ("id", integer()),
            ("x_m", number()),
            ("y_m", number()),
            ("v_mps", number()),
            ("a_mps2", number()),
            ("vy_mps", number()),
            ("length_m", number()),
            ("width_m", number()),
        ],
        &["vy_mps", "length_m", "width_m"],
    );
    titled(
        "hmdp.PlanRequest",
        object(
            &[
                ("version", integer()),
                ("vehicle_id", integer()),
                ("sequence", integer()),
                ("timestamp_ns", integer()),
                ("deadline_us", integer()),
                ("sent_at_ns", integer()),
                ("road", road),
                ("ego", ego),
                ("svs", array(sv)),
                ("memory", memory()),
            ],
            &["deadline_us", "sent_at_ns", "memory"],
        ),
    )
}

/// `protocol::PlanResponse`.
pub fn plan_response() -> Value {
    let step = object(
        &[
            ("action", action()),
            ("maneuver", maneuver()),
            ("x_m", number()),
            ("v_mps", number()),
            ("occupied_lanes", integer()),
        ],
        &[],
    );
    let layer = json!({ "type": "string", "enum": ["nominal", "global_relaxation", "fallback", "watchdog_fallback", "stale_fallback"] });
    let decided = object(
        &[
            ("action", action()),
            ("next_maneuver", maneuver()),
            (
                "setpoint",
                object(&[("accel_mps2", number()), ("target_speed_mps", number())], &[]),
            ),
            ("plan", array(step)),
            ("layer", layer),
            ("memory", memory()),
        ],
        &[],
    );
    let rejected = object(
        &[
            ("reason", json!({ "type": "string" })),
            ("field", json!({ "type": "string" })),
        ],
        &[],
    );
    let outcome = json!({
        "oneOf": [
            object(&[("decided", decided)], &[]),
            object(&[("rejected", rejected)], &[]),
        ]
    });
    titled(
        "hmdp.PlanResponse",
        object(
            &[
                ("version", integer()),
                ("vehicle_id", integer()),
                ("sequence", integer()),
                ("solve_us", integer()),
                ("queue_us", integer()),
                ("outcome", outcome),
                ("signature", json!({ "type": "string" })),
            ],
            &["signature"],
        ),
    )
}

/// The service's statistics document (`planner::service::StatsSnapshot`).
pub fn planner_stats() -> Value {
    let layers = object(
        &[
            ("nominal", integer()),
            ("global_relaxation", integer()),
            ("fallback", integer()),
            ("watchdog_fallback", integer()),
            ("stale_fallback", integer()),
            ("rejected", integer()),
        ],
        &["stale_fallback"],
    );
    let percentiles = object(
        &[
            ("count", integer()),
            ("mean_us", number()),
            ("p50_us", integer()),
            ("p90_us", integer()),
            ("p99_us", integer()),
            ("p999_us", integer()),
            ("max_us", integer()),
        ],
        &[],
    );
    titled(
        "hmdp.PlannerStats",
        object(
            &[
                ("uptime_s", number()),
                ("answered", integer()),
                ("by_layer", layers),
                ("probes", integer()),
                ("overloaded", integer()),
                ("late_discarded", integer()),
                ("latency", percentiles.clone()),
                ("solve", percentiles),
            ],
            &[],
        ),
    )
}
