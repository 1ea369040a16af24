//! The fallback's band case, in the paper-literal preset (`deploy/paper.toml`): with the
//! paper's slack bound the band row asks `gap >= d_trig` at every step, so an ego that enters
//! corrective mode deeper in the band than it can brake out of within the horizon has no
//! nominal plan. The fallback must then open the gap (brake), not hold the ego just outside
//! the IDM distance, where the nominal problem would stay infeasible.

mod common;

use common::{ClosedLoop, Vehicle};
use decision::{Layer, PlannerConfig};

fn paper() -> PlannerConfig {
    PlannerConfig::from_toml_str(include_str!("../../deploy/paper.toml")).unwrap()
}

/// The ego at 20 m/s, 65 m behind a leader holding 15 m/s: beyond the IDM distance (about
/// 61 m at these speeds, `T = 1.5 s`, `b = 2`), inside the trigger distance (about 22 m more).
fn deep_in_the_band(leader: Vehicle) -> common::Trace {
    ClosedLoop {
        config: paper(),
        lanes: 1,
        desired_speed_mps: 25.0,
        ego_v_mps: 20.0,
        vehicles: vec![leader],
        duration_s: 30.0,
    }
    .run()
}

#[test]
fn entering_deep_in_the_band_the_fallback_brakes_until_the_nominal_plan_is_back() {
    // (What the preset does after that is the paper's frozen band at one fixed deceleration:
    // it brakes the slack away, speeds up again and triggers anew, docs/paper-literal.md.)
    let trace = deep_in_the_band(Vehicle::steady(70.0, 15.0));
    let first = &trace.decisions[0];
    assert_eq!(first.layer, Layer::Fallback, "the band leaves no nominal plan here");
    // The state's one deceleration, where holding speed would close in at 5 m/s.
    assert_eq!(first.accel_mps2, -3.0);
    // Back to the nominal MPC within 6 s (15 decisions), once the gap reached the trigger
    // distance.
    let back = trace.decisions.iter().position(|d| d.layer == Layer::Nominal);
    assert!(back.is_some_and(|k| k < 15), "first nominal decision {back:?}");
    // Braking held the ego beyond the IDM distance throughout.
    assert!(trace.least_gap_m >= 60.0, "least gap {}", trace.least_gap_m);
}
