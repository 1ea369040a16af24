//! A violation already present or predicted within the horizon (`idm.violation_recovery_mps2`):
//! an SV cutting in deep inside the ego's IDM distance is recovered from by comfortable
//! braking, not answered by the fallback or the strongest braking.

use decision::{EgoState, Layer, Maneuver, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation};

/// Three lanes 4 m wide (lane 3 at y = 0); the ego in lane 3 at 36.7 m/s, accelerating; an SV
/// 28 m/s, `dx` ahead, at lane 2's centre and moving right at 2.5 m/s: the tree's lane-change
/// branch (near certain at that lateral speed) puts it into the ego's lane from the first
/// step, deep inside the ego's IDM distance (about 150 m), not now.
fn cut_in(dx: f64, beta: i8) -> Situation {
    Situation {
        road: Road {
            lanes: 3,
            lane_width_m: 4.0,
            speed_limit_mps: 40.0,
        },
        ego: EgoState {
            x_m: 0.0,
            y_m: 0.0,
            v_mps: 36.7,
            desired_speed_mps: 38.0,
            maneuver: Maneuver { lane: 3, beta },
        },
        svs: vec![SvObservation {
            vy_mps: -2.5,
            ..SvObservation::new(2, dx, 3.95, 28.0, 0.0)
        }],
        memory: PlannerMemory::default(),
    }
}

fn decide(recovery: f64, s: &Situation) -> decision::Decision {
    let mut config = PlannerConfig::default();
    config.idm.violation_recovery_mps2 = recovery;
    Planner::new(config).unwrap().decide(s).unwrap()
}

#[test]
fn a_cut_in_a_step_away_is_recovered_by_comfortable_braking() {
    for beta in [1, 0, -1] {
        let s = cut_in(43.0, beta);
        let d = decide(PlannerConfig::default().idm.violation_recovery_mps2, &s);
        assert_eq!(d.layer, Layer::Nominal, "beta {beta}: {d:?}");
        let end = d.plan.last().unwrap().v_mps;
        assert!(end < s.ego.v_mps - 0.5, "beta {beta}: slows down, ends at {end}");
        let accels: Vec<f64> = std::iter::once(s.ego.v_mps)
            .chain(d.plan.iter().map(|p| p.v_mps))
            .collect::<Vec<_>>()
            .windows(2)
            .map(|w| (w[1] - w[0]) / 0.4)
            .collect();
        assert!(
            accels.iter().all(|&a| a >= -2.0 - 1e-6),
            "beta {beta}: no planned braking beyond the comfort level: {accels:?}"
        );
    }
}

#[test]
fn without_the_recovery_the_same_cut_in_leaves_the_nominal_layer() {
    // The decay alone asks the 100 m violation to shrink by a fifth per step: no plan from an
    // accelerating state achieves it, and a recovery layer answers.
    let d = decide(0.0, &cut_in(43.0, 1));
    assert_ne!(d.layer, Layer::Nominal, "{d:?}");
}

#[test]
fn the_floor_still_holds_for_a_cut_in_at_the_bumper() {
    // 1 m bumper to bumper and closing at 8.7 m/s: no comfortable braking keeps the jam
    // distance, so the answer brakes harder than the recovery, or is not nominal.
    let length = PlannerConfig::default().vehicle.length_m;
    let d = decide(1.5, &cut_in(length + 1.0, 0));
    let first = d.setpoint.accel_mps2;
    assert!(
        d.layer != Layer::Nominal || first < -1.5 - 1e-6,
        "{:?} {first}",
        d.layer
    );
    assert_eq!(d.next_maneuver.beta, -1, "{d:?}");
}
