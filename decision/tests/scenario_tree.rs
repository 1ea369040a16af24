//! The SV scenario tree with evidence (`prediction.evidence`, decision/src/evidence.rs): a
//! branch survives where the evidence makes it likely, and changes the decision.

use decision::problem::prepare;
use decision::{
    Action, EgoState, Layer, Maneuver, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation,
};

/// Three 4 m lanes (lane 1 at y = 8, the ego's lane 2 at 4); the ego at 25 m/s wanting 30,
/// cruising. SV 1 is 30 m ahead in lane 1 at the ego's speed, drifting towards the ego's lane
/// at `vy`; with `held_up`, SV 2 is 25 m ahead of it in lane 1 at 18 m/s.
fn scene(vy: f64, held_up: bool) -> Situation {
    let mut svs = vec![SvObservation {
        vy_mps: vy,
        ..SvObservation::new(1, 30.0, 7.95, 25.0, 0.0)
    }];
    if held_up {
        svs.push(SvObservation::new(2, 55.0, 8.0, 18.0, 0.0));
    }
    Situation {
        road: Road {
            lanes: 3,
            lane_width_m: 4.0,
            speed_limit_mps: 35.0,
        },
        ego: EgoState {
            x_m: 0.0,
            y_m: 4.0,
            v_mps: 25.0,
            desired_speed_mps: 30.0,
            maneuver: Maneuver { lane: 2, beta: 0 },
        },
        svs,
        memory: PlannerMemory::default(),
    }
}

/// SV 1's kept branches: `(probability, whether it changes into the ego's lane)`.
fn sv1_branches(config: &PlannerConfig, s: &Situation) -> Vec<(f64, bool)> {
    let prepared = prepare(config, s);
    let sv = prepared.problem.svs.iter().find(|c| c.id == 1).expect("SV 1 in range");
    sv.branches
        .iter()
        .map(|b| (b.probability, b.maneuvers.iter().any(|m| m.lane == 2)))
        .collect()
}

fn decide(config: &PlannerConfig, s: &Situation) -> decision::Decision {
    Planner::new(config.clone()).unwrap().decide(s).unwrap()
}

/// SV 1 drifts at 0.15 m/s, below the lateral extrapolation's threshold (0.2 m/s) and inside
/// the lane-centre tolerance: only the tree's lane-change branch, made likely by the drift and
/// by the slower car holding SV 1 up, sees it coming into the ego's lane. The ego then does not
/// accelerate towards it; without the branch (the same scene with the extrapolation instead of
/// the evidence, or without the drift and the slower car) it accelerates.
#[test]
fn a_cut_in_only_the_trees_branch_anticipates() {
    let config = PlannerConfig::default();
    let cut_in = scene(-0.15, true);
    let branches = sv1_branches(&config, &cut_in);
    let change: Vec<f64> = branches.iter().filter(|b| b.1).map(|b| b.0).collect();
    assert!(
        !change.is_empty() && change[0] >= 0.1,
        "no lane-change branch into the ego's lane: {branches:?}"
    );
    assert!(branches.iter().any(|b| !b.1), "the keep branch stays: {branches:?}");
    let anticipating = decide(&config, &cut_in);
    assert_eq!(anticipating.layer, Layer::Nominal);
    assert!(anticipating.next_maneuver.beta <= 0, "{anticipating:?}");

    // The extrapolation alone (the earlier prediction) does not see it: below its threshold,
    // the ego accelerates, ending the horizon over 1 m/s faster.
    let mut extrapolating = config.clone();
    extrapolating.prediction.evidence.enabled = false;
    extrapolating.prediction.lateral_velocity_threshold_mps = 0.2;
    assert!(sv1_branches(&extrapolating, &cut_in).iter().all(|b| !b.1));
    let unaware = decide(&extrapolating, &cut_in);
    assert_eq!(unaware.next_maneuver.beta, 1, "{unaware:?}");
    let end = |d: &decision::Decision| d.plan.last().map_or(0.0, |s| s.v_mps);
    assert!(
        end(&unaware) > end(&anticipating) + 1.0,
        "{unaware:?}\n{anticipating:?}"
    );

    // Nothing telling, no branch: the ego accelerates.
    let quiet = scene(0.0, false);
    assert!(sv1_branches(&config, &quiet).iter().all(|b| !b.1));
    let d = decide(&config, &quiet);
    assert_eq!(d.next_maneuver.beta, 1, "{d:?}");
    assert_eq!(
        d.action,
        Action {
            lateral: 0,
            longitudinal: 1
        }
    );
}

/// In quiet traffic the tree stays one branch per SV, at any horizon: the evidence's branches
/// are not background noise kept as hard rows.
#[test]
fn quiet_traffic_keeps_one_branch_per_sv() {
    for horizon in [3, 6] {
        let mut config = PlannerConfig::default();
        config.timing.horizon = horizon;
        let s = scene(0.0, false);
        assert_eq!(sv1_branches(&config, &s).len(), 1, "H = {horizon}");
    }
}

/// A leader closing in fast on a slower car ahead of it will brake: its braking branch is
/// kept beside the keep branch, at H = 6 too.
#[test]
fn a_leader_closing_in_on_its_own_leader_gets_a_braking_branch() {
    for horizon in [3, 6] {
        let mut config = PlannerConfig::default();
        config.timing.horizon = horizon;
        let mut s = scene(0.0, false);
        // In the ego's lane: SV 1 at 40 m, at 25 m/s, 25 m behind a car at 15 m/s.
        s.svs = vec![
            SvObservation::new(1, 40.0, 4.0, 25.0, 0.0),
            SvObservation::new(2, 70.0, 4.0, 15.0, 0.0),
        ];
        let prepared = prepare(&config, &s);
        let sv = prepared.problem.svs.iter().find(|c| c.id == 1).unwrap();
        assert!(
            sv.branches
                .iter()
                .any(|b| b.actions[0].longitudinal == -1 && b.probability >= 0.1),
            "H = {horizon}: {:?}",
            sv.branches
                .iter()
                .map(|b| (b.probability, b.actions.clone()))
                .collect::<Vec<_>>()
        );
    }
}
