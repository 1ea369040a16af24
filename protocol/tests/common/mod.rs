//! Strategies and example messages shared by the integration tests.
#![allow(dead_code)]

use proptest::collection::vec;
use proptest::prelude::*;
use protocol::containers::{StaticVec, Vector};
use protocol::*;

pub fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1.0e7..1.0e7f64,
        any::<f64>().prop_filter("finite", |v| v.is_finite()),
        Just(0.0),
        Just(-0.0),
    ]
}

pub fn unit() -> impl Strategy<Value = i8> {
    -1i8..=1
}

pub fn list<T: Clone + core::fmt::Debug, const N: usize>(items: Vec<T>) -> StaticVec<T, N> {
    let mut out = StaticVec::new();
    for item in items {
        out.push(item).unwrap();
    }
    out
}

pub fn maneuver() -> impl Strategy<Value = Maneuver> {
    (any::<u8>(), unit()).prop_map(|(lane, beta)| Maneuver { lane, beta })
}

pub fn action() -> impl Strategy<Value = Action> {
    (unit(), unit()).prop_map(|(lateral, longitudinal)| Action { lateral, longitudinal })
}

pub fn road() -> impl Strategy<Value = Road> {
    (any::<u8>(), finite(), finite()).prop_map(|(lanes, lane_width_m, speed_limit_mps)| Road {
        lanes,
        lane_width_m,
        speed_limit_mps,
    })
}

pub fn ego() -> impl Strategy<Value = EgoState> {
    (finite(), finite(), finite(), finite(), maneuver()).prop_map(|(x_m, y_m, v_mps, desired_speed_mps, maneuver)| {
        EgoState {
            x_m,
            y_m,
            v_mps,
            desired_speed_mps,
            maneuver,
        }
    })
}

pub fn sv() -> impl Strategy<Value = SvObservation> {
    (
        any::<u32>(),
        finite(),
        finite(),
        finite(),
        finite(),
        finite(),
        finite(),
        finite(),
    )
        .prop_map(
            |(id, x_m, y_m, v_mps, a_mps2, vy_mps, length_m, width_m)| SvObservation {
                id,
                x_m,
                y_m,
                v_mps,
                a_mps2,
                vy_mps,
                length_m,
                width_m,
            },
        )
}

pub fn setpoint() -> impl Strategy<Value = SetPoint> {
    (finite(), finite()).prop_map(|(accel_mps2, target_speed_mps)| SetPoint {
        accel_mps2,
        target_speed_mps,
    })
}

pub fn corrective() -> impl Strategy<Value = CorrectiveEntry> {
    (any::<u32>(), finite(), finite()).prop_map(|(sv_id, release_m, trigger_m)| CorrectiveEntry {
        sv_id,
        release_m,
        trigger_m,
    })
}

pub fn memory() -> impl Strategy<Value = PlannerMemory> {
    (vec(corrective(), 0..=MAX_CORRECTIVE), vec(action(), 0..=MAX_HORIZON)).prop_map(|(c, p)| PlannerMemory {
        corrective: list(c),
        previous_plan: list(p),
    })
}

pub fn request() -> impl Strategy<Value = PlanRequest> {
    (
        (any::<u64>(), any::<u64>(), any::<u64>(), any::<u32>(), any::<u64>()),
        road(),
        ego(),
        vec(sv(), 0..=MAX_SVS),
        memory(),
    )
        .prop_map(
            |((vehicle_id, sequence, timestamp_ns, deadline_us, sent_at_ns), road, ego, svs, memory)| {
                let mut r = PlanRequest::new(vehicle_id, sequence, timestamp_ns, road, ego);
                r.deadline_us = deadline_us;
                r.sent_at_ns = sent_at_ns;
                r.svs = list(svs);
                r.memory = memory;
                r
            },
        )
}

pub fn plan_step() -> impl Strategy<Value = PlanStep> {
    (action(), maneuver(), finite(), finite(), any::<u16>()).prop_map(
        |(action, maneuver, x_m, v_mps, occupied_lanes)| PlanStep {
            action,
            maneuver,
            x_m,
            v_mps,
            occupied_lanes,
        },
    )
}

pub fn layer() -> impl Strategy<Value = Layer> {
    proptest::sample::select(Layer::ALL)
}

pub fn reason() -> impl Strategy<Value = RejectReason> {
    proptest::sample::select(RejectReason::ALL)
}

pub fn field_name() -> impl Strategy<Value = String> {
    "[a-z_.]{0,31}"
}

pub fn response() -> impl Strategy<Value = PlanResponse> {
    let decided = (
        action(),
        maneuver(),
        setpoint(),
        vec(plan_step(), 0..=MAX_HORIZON),
        layer(),
        memory(),
    )
        .prop_map(|(a, m, sp, plan, layer, memory)| {
            Outcome::decided(Decided::new(a, m, sp, list(plan), layer, memory))
        });
    let rejected = (reason(), field_name()).prop_map(|(r, f)| Outcome::rejected(Rejected::new(r, &f)));
    (
        any::<u64>(),
        any::<u64>(),
        any::<u32>(),
        any::<u32>(),
        prop_oneof![decided, rejected],
        prop_oneof![
            Just(Signature::UNSIGNED),
            vec(any::<u8>(), SIGNATURE_LENGTH).prop_map(signature)
        ],
    )
        .prop_map(
            |(vehicle_id, sequence, solve_us, queue_us, outcome, signature)| PlanResponse {
                version: PROTOCOL_VERSION,
                vehicle_id,
                sequence,
                solve_us,
                queue_us,
                outcome,
                signature,
            },
        )
}

fn signature(bytes: Vec<u8>) -> Signature {
    Signature(bytes.try_into().unwrap_or([0; SIGNATURE_LENGTH]))
}

/// The documented example key (a secret everybody knows: for tests and examples only).
pub fn example_signer() -> ResponseSigner {
    ResponseSigner::from_seed(&[0x01; 32])
}

/// The small request documented byte for byte in docs/protocol.md.
pub fn example_request() -> PlanRequest {
    let road = Road {
        lanes: 3,
        lane_width_m: 3.5,
        speed_limit_mps: 30.0,
    };
    let ego = EgoState {
        x_m: 0.0,
        y_m: 3.5,
        v_mps: 25.0,
        desired_speed_mps: 28.0,
        maneuver: Maneuver { lane: 2, beta: 0 },
    };
    let mut r = PlanRequest::new(7, 42, 1_000_000_000, road, ego);
    r.sent_at_ns = 1_767_225_600_000_000_000;
    r.svs
        .push(SvObservation {
            vy_mps: 0.25,
            length_m: 4.5,
            ..SvObservation::new(1, 30.0, 3.5, 20.0, -0.5)
        })
        .unwrap();
    r.memory
        .previous_plan
        .push(Action {
            lateral: 0,
            longitudinal: 1,
        })
        .unwrap();
    r
}

/// The decided response documented in docs/protocol.md.
pub fn example_response() -> PlanResponse {
    let keep = Action {
        lateral: 0,
        longitudinal: 0,
    };
    let m = Maneuver { lane: 2, beta: 0 };
    let plan = list(vec![
        PlanStep {
            action: keep,
            maneuver: m,
            x_m: 10.0,
            v_mps: 25.0,
            occupied_lanes: 0b010,
        },
        PlanStep {
            action: Action {
                lateral: -1,
                longitudinal: 0,
            },
            maneuver: Maneuver { lane: 1, beta: 0 },
            x_m: 20.0,
            v_mps: 25.0,
            occupied_lanes: 0b011,
        },
    ]);
    let memory = PlannerMemory {
        corrective: list(vec![CorrectiveEntry {
            sv_id: 1,
            release_m: 40.0,
            trigger_m: 30.0,
        }]),
        previous_plan: list(vec![
            keep,
            Action {
                lateral: -1,
                longitudinal: 0,
            },
        ]),
    };
    let setpoint = SetPoint {
        accel_mps2: 0.0,
        target_speed_mps: 25.0,
    };
    let mut r = PlanResponse::decided(
        7,
        42,
        Decided::new(keep, m, setpoint, plan, Layer::Nominal, memory),
        1850,
        12,
    );
    example_signer().sign(&mut r);
    r
}

/// The rejection documented in docs/protocol.md.
pub fn example_rejection() -> PlanResponse {
    PlanResponse::rejected(7, 43, Rejected::new(RejectReason::NegativeSpeed, "ego.v_mps"), 5)
}
