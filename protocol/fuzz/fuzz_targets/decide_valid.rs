//! Requests that pass the wire checks, through the decision core as the service runs it: the
//! planner (`Planner::decide`, enumeration backend, default configuration) and the watchdog's
//! fallback (`decision::fallback_only`). Either may refuse with a typed error; neither may
//! panic, and a decision must fit the response.
//!
//! Inputs are built with `arbitrary`, biased towards plausible scenes (positions near lane
//! centres, speeds in range) so that most of them get past the core's own input checks and
//! reach the solver; the rest are edge values (limits, NaN, infinities, raw bits).
//! Set `HMDP_FUZZ_MILP=1` to also run the MILP backend on each input (slower).
#![no_main]

use std::cell::RefCell;

use arbitrary::{Result, Unstructured};
use decision::{Backend, DecisionError, Planner, PlannerConfig};
use libfuzzer_sys::fuzz_target;
use protocol::containers::Vector;
use protocol::{
    Action, CorrectiveEntry, Decided, EgoState, Maneuver, PlanRequest, PlanResponse, Rejected, Road, SvObservation,
    MAX_CORRECTIVE, MAX_HORIZON, MAX_SVS,
};

/// Values at and just past the core's plausibility limits, and the non-finite ones.
const EDGES: &[f64] = &[
    0.0,
    -0.0,
    f64::MIN_POSITIVE,
    1.0e-300,
    0.5,
    20.0,
    20.000000000000004,
    100.0,
    -100.0,
    150.0,
    150.00000000000003,
    1.0e7,
    -1.0e7,
    1.0e7 + 2.0,
    f64::MAX,
    f64::MIN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NAN,
];

/// A number in `[lo, hi]` most of the time, otherwise an edge value or raw bits.
fn num(u: &mut Unstructured, lo: f64, hi: f64) -> Result<f64> {
    Ok(match u.int_in_range(0u8..=15)? {
        0 => *u.choose(EDGES)?,
        1 => f64::from_bits(u.arbitrary()?),
        _ => lo + (hi - lo) * f64::from(u.arbitrary::<u16>()?) / f64::from(u16::MAX),
    })
}

/// A lateral position: on a lane centre, between lanes, or anywhere.
fn lateral(u: &mut Unstructured, road: &Road) -> Result<f64> {
    let lanes = f64::from(road.lanes.max(1));
    let lane = f64::from(u.int_in_range(1..=road.lanes.max(1))?);
    let centre = (lanes - lane) * road.lane_width_m;
    Ok(match u.int_in_range(0u8..=7)? {
        0..=4 => centre,
        5 | 6 => centre + num(u, -1.0, 1.0)? * road.lane_width_m,
        _ => num(u, -10.0, 80.0)?,
    })
}

fn small(u: &mut Unstructured) -> Result<i8> {
    // Mostly -1..=1; sometimes anything, which the wire checks must catch.
    Ok(if u.ratio(1u8, 16)? {
        u.arbitrary()?
    } else {
        u.int_in_range(-1..=1)?
    })
}

fn request(u: &mut Unstructured) -> Result<PlanRequest> {
    let lanes = if u.ratio(1u8, 16)? {
        u.arbitrary()?
    } else {
        u.int_in_range(1..=8)?
    };
    let road = Road {
        lanes,
        lane_width_m: num(u, 2.5, 5.0)?,
        speed_limit_mps: num(u, 0.0, 50.0)?,
    };
    let lane = if u.ratio(1u8, 16)? {
        u.arbitrary()?
    } else {
        u.int_in_range(1..=lanes.max(1))?
    };
    let ego = EgoState {
        x_m: num(u, -100.0, 100.0)?,
        y_m: lateral(u, &road)?,
        v_mps: num(u, 0.0, 45.0)?,
        desired_speed_mps: num(u, 0.0, 45.0)?,
        maneuver: Maneuver { lane, beta: small(u)? },
    };
    let mut r = PlanRequest::new(u.arbitrary()?, u.arbitrary()?, u.arbitrary()?, road, ego);
    r.deadline_us = u.arbitrary()?;
    r.sent_at_ns = u.arbitrary()?;
    for _ in 0..u.int_in_range(0..=MAX_SVS)? {
        let sv = SvObservation {
            // A small id space makes duplicates (a typed rejection) reachable.
            id: if u.ratio(1u8, 4)? {
                u.arbitrary()?
            } else {
                u.int_in_range(0..=20)?
            },
            x_m: num(u, -150.0, 200.0)?,
            y_m: lateral(u, &road)?,
            v_mps: num(u, -0.6, 45.0)?,
            a_mps2: num(u, -8.0, 4.0)?,
            vy_mps: num(u, -2.0, 2.0)?,
            // 0 = unknown; a few implausible sizes reach the planner's range checks.
            length_m: if u.ratio(1u8, 3)? { 0.0 } else { num(u, -1.0, 25.0)? },
            width_m: if u.ratio(1u8, 3)? { 0.0 } else { num(u, -1.0, 4.0)? },
        };
        let _ = r.svs.push(sv);
    }
    for _ in 0..u.int_in_range(0..=MAX_CORRECTIVE)? {
        let trigger_m = num(u, 0.0, 100.0)?;
        let entry = CorrectiveEntry {
            sv_id: u.int_in_range(0..=20)?,
            release_m: if u.ratio(1u8, 8)? {
                num(u, -10.0, 100.0)?
            } else {
                trigger_m + num(u, 0.0, 30.0)?
            },
            trigger_m,
        };
        let _ = r.memory.corrective.push(entry);
    }
    for _ in 0..u.int_in_range(0..=MAX_HORIZON)? {
        let _ = r.memory.previous_plan.push(Action {
            lateral: small(u)?,
            longitudinal: small(u)?,
        });
    }
    Ok(r)
}

fn planner(backend: Backend) -> Planner {
    let mut config = PlannerConfig::default();
    config.solver.backend = backend;
    Planner::new(config).expect("the default configuration is valid")
}

thread_local! {
    // One planner per backend for the whole run, as in the service (HiGHS set-up is costly).
    static ENUMERATION: RefCell<Planner> = RefCell::new(planner(Backend::Enumeration));
    static MILP: Option<RefCell<Planner>> =
        std::env::var_os("HMDP_FUZZ_MILP").map(|_| RefCell::new(planner(Backend::Milp)));
}


/// A decision must travel back in a response; an error must be an input error (the request
/// passed the wire checks, the configuration is valid and the enumeration calls no solver).
fn check(request: &PlanRequest, result: &core::result::Result<decision::Decision, DecisionError>, milp: bool) {
    match result {
        Ok(d) => {
            let decided = Decided::try_from(d).expect("a decision fits the response");
            let response = PlanResponse::decided(request.vehicle_id, request.sequence, decided, 0, 0);
            if let Err(e) = response.validate() {
                panic!("the response to {request:?} is invalid ({e:?}): {d:?}");
            }
        }
        Err(DecisionError::Input(e)) => {
            Rejected::from(e).reason().expect("input errors have known reasons");
        }
        // HiGHS can fail on its own (a typed error the service reports as internal).
        Err(DecisionError::Solver(_)) if milp => {}
        Err(e) => panic!("unexpected error for a request that passed the wire checks: {e:?}"),
    }
}


fuzz_target!(|data: &[u8]| {
    let mut u = Unstructured::new(data);
    let Ok(request) = request(&mut u) else { return };
    if request.check_wire().is_err() {
        return;
    }
    let situation = request.to_situation();
    let decided = ENUMERATION.with(|p| p.borrow_mut().decide(&situation));
    check(&request, &decided, false);
    // The watchdog answers with the fallback alone, for the requests that pass every check.
    let config = PlannerConfig::default();
    let fallback = decision::ValidSituation::new(&config, &situation)
        .map(|valid| decision::fallback_only(&config, &valid))
        .map_err(DecisionError::from);
    check(&request, &fallback, false);
    // `validate` runs the same input checks as `decide`.
    assert_eq!(
        decided.as_ref().err().map(Rejected::from),
        fallback.as_ref().err().map(Rejected::from)
    );
    MILP.with(|m| {
        if let Some(p) = m {
            let result = p.borrow_mut().decide(&situation);
            check(&request, &result, true);
        }
    });
});
