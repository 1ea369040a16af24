//! The terminal lane value (`cost.lane_lookahead_m`, `cost.lane_horizon_s`): a slow truck
//! just beyond a cut-off distance must not make its lane look free.
//!
//! The situation is a recorded SUMO decision (`2lanes-dense`, seed 1011, t = 150.9 s, SVs
//! within the perception window, positions relative to the ego): the ego in the left lane
//! at 29.5 m/s behind a 28.4 m/s leader 49 m ahead, in corrective mode on it, its lane
//! flowing at 30-32 m/s beyond; in the right lane 25 m/s trucks 110 and 191 m ahead. With
//! the lane value's former 100 m cut-off the planner changed into the right lane and stayed
//! behind the first truck for the rest of the episode (26.2 m/s mean against Krauss's 32.1).

use decision::{Decision, Planner, PlannerConfig, Situation};

fn recorded() -> Situation {
    serde_json::from_str(include_str!("data/lane_value_2lanes_dense_1011.json")).unwrap()
}

fn without(mut s: Situation, ids: &[u32]) -> Situation {
    s.svs.retain(|sv| !ids.contains(&sv.id));
    s
}

fn decide(config: PlannerConfig, s: &Situation) -> Decision {
    Planner::new(config).unwrap().decide(s).unwrap()
}

/// The former lane value: the slowest SV within 100 m, at its full weight.
fn cut_off_at_100_m() -> PlannerConfig {
    let mut config = PlannerConfig::default();
    config.cost.lane_lookahead_m = 100.0;
    config.cost.lane_horizon_s = 0.0;
    config
}

#[test]
fn a_slow_truck_beyond_100_m_keeps_the_ego_in_its_lane() {
    let s = recorded();
    let d = decide(PlannerConfig::default(), &s);
    assert_eq!(d.next_maneuver.lane, 1, "{d:?}");
    // The situation discriminates: with the cut-off the right lane looked free.
    let cut = decide(cut_off_at_100_m(), &s);
    assert_eq!(cut.next_maneuver.lane, 2, "{cut:?}");
}

#[test]
fn a_free_lane_is_still_worth_changing_into() {
    // Without the trucks the right lane is free within the perception window: the ego
    // leaves its leader's band for it.
    let d = decide(PlannerConfig::default(), &without(recorded(), &[11, 12]));
    assert_eq!(d.next_maneuver.lane, 2, "{d:?}");
}
