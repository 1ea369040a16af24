//! The lateral extrapolation of an SV moving sideways (`prediction.lateral_velocity_threshold_mps`,
//! `prediction.lateral_departure`), the prediction without evidence in the tree: a drifting
//! SV enters the ego's lane in the prediction before it leaves its own lane centre, and an SV
//! leaving the ego's lane leaves it in the prediction once its extrapolated position reaches
//! the next lane centre. (With the evidence, the default, the tree's lane-change branch does
//! this: tests/scenario_tree.rs.)

use decision::config::LateralDeparture;
use decision::lanes::LaneSet;
use decision::problem::prepare;
use decision::{EgoState, Maneuver, PlannerConfig, PlannerMemory, Road, Situation, SvObservation};

/// Three lanes 4 m wide (lane 3 at y = 0, lane 2 at 4, lane 1 at 8); the ego in lane 2 at
/// 25 m/s; one SV 40 m ahead at `y` moving sideways at `vy`.
fn situation(y: f64, vy: f64) -> Situation {
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
        svs: vec![SvObservation {
            vy_mps: vy,
            ..SvObservation::new(7, 40.0, y, 22.0, 0.0)
        }],
        memory: PlannerMemory::default(),
    }
}

/// The lanes the SV's most probable branch occupies at each step for the hard rows, and for
/// the hysteresis.
fn predicted_lanes(config: &PlannerConfig, s: &Situation) -> (Vec<LaneSet>, Vec<LaneSet>) {
    let prepared = prepare(config, s);
    let sv = prepared
        .problem
        .svs
        .iter()
        .find(|c| c.id == 7)
        .expect("the SV is in range");
    (sv.branches[0].occupancy.clone(), sv.mean_occupancy.clone())
}

/// The extrapolation instead of the evidence.
fn extrapolating() -> PlannerConfig {
    let mut config = PlannerConfig::default();
    config.prediction.evidence.enabled = false;
    config.prediction.lateral_velocity_threshold_mps = 0.2;
    config
}

fn with_departure(departure: LateralDeparture) -> PlannerConfig {
    let mut config = extrapolating();
    config.prediction.lateral_departure = departure;
    config.prediction.departure_speed_share = 0.5;
    config
}

const LANE_1: LaneSet = LaneSet(0b001);
const LANES_1_2: LaneSet = LaneSet(0b011);
const LANES_2_3: LaneSet = LaneSet(0b110);

#[test]
fn an_sv_leaving_the_egos_lane_leaves_it_once_predicted_at_the_next_centre() {
    // 2.5 m towards lane 1 at 4 m/s, its departure extrapolated at half that: at 6.5 + 0.8 m
    // after one step (lanes 1 and 2), at 8.1 and 8.9 m after two and three (lane 1 only:
    // within the 0.1 m tolerance of its centre, then past the centre of the outermost lane,
    // which clamps it there).
    assert_eq!(
        PlannerConfig::default().prediction.lateral_departure,
        LateralDeparture::Always
    );
    let leaving = situation(4.0 + 2.5, 4.0);
    let held = vec![LANES_1_2; 3];
    let departed = vec![LANES_1_2, LANE_1, LANE_1];
    for (departure, hard, band) in [
        (LateralDeparture::Never, &held, &held),
        (LateralDeparture::Band, &held, &departed),
        (LateralDeparture::Always, &departed, &departed),
    ] {
        let (h, b) = predicted_lanes(&with_departure(departure), &leaving);
        assert_eq!((&h, &b), (hard, band), "{departure:?}");
    }
    // At the full lateral velocity it is at 8.1 m after one step already.
    let mut full = with_departure(LateralDeparture::Always);
    full.prediction.departure_speed_share = 1.0;
    assert_eq!(predicted_lanes(&full, &leaving).0, vec![LANE_1; 3]);
}

#[test]
fn a_drifting_sv_enters_the_egos_lane_before_it_leaves_its_own_centre() {
    // 0.05 m off lane 3's centre (inside the 0.1 m tolerance: lane 3 only now), drifting
    // towards the ego's lane at 1.5 m/s: off the centre after one step (lanes 2 and 3).
    for departure in [
        LateralDeparture::Never,
        LateralDeparture::Band,
        LateralDeparture::Always,
    ] {
        let (hard, band) = predicted_lanes(&with_departure(departure), &situation(0.05, 1.5));
        for lanes in [hard, band] {
            assert!(lanes.iter().all(|l| l.contains(2)), "{departure:?}: {lanes:?}");
            assert_eq!(lanes[0], LANES_2_3, "{departure:?}");
        }
    }
}

#[test]
fn below_the_threshold_an_sv_keeps_its_lane() {
    let config = extrapolating();
    let slow = config.prediction.lateral_velocity_threshold_mps * 0.5;
    let (hard, band) = predicted_lanes(&config, &situation(8.0, -slow));
    assert_eq!((hard, band), (vec![LANE_1; 3], vec![LANE_1; 3]));
}
