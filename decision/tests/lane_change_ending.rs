//! An SV ending a lane change beside the ego (`evidence::first_step`): its lateral speed
//! towards its new lane's centre is the change it finishes, not a cut-in into the ego's lane.
//! Read as a start, it had the ego brake at 6 m/s^2 for a cut-in that never came: one of the
//! causes of the held-out campaign's hard braking (docs/braking-leader.md).

use decision::{Decision, Planner, PlannerConfig, Situation};

/// A recorded held-out decision (`sim_client campaign --config
/// sim_client/campaigns/held-out.toml --seed 4242 --trace-hard-braking`, configuration 1,
/// trial 206, t = 22.0 s): the ego at its desired 30 m/s in lane 1; SV 7 alongside (2.9 m
/// ahead, centre to centre) at 28.1 m/s, 1 cm short of lane 2's centre and still moving up
/// into it at 0.24 m/s, the end of its change from lane 3.
fn recorded() -> Situation {
    serde_json::from_str(include_str!("data/arriving_sv_held_out_4242.json")).unwrap()
}

fn decide(s: &Situation) -> Decision {
    Planner::new(PlannerConfig::default()).unwrap().decide(s).unwrap()
}

#[test]
fn an_sv_finishing_its_change_beside_the_ego_is_no_cut_in() {
    let s = recorded();
    let d = decide(&s);
    assert!(d.setpoint.accel_mps2 > -0.5, "{d:?}");
    // It discriminates: mirrored across the lane centre (1 cm past it, moving on away from
    // it) the same SV is starting a change into the ego's lane, and the ego brakes hard.
    let mut starting = s.clone();
    let centre = starting.road.lane_centre(2);
    let sv = &mut starting.svs[0];
    sv.y_m = 2.0 * centre - sv.y_m;
    let d = decide(&starting);
    assert!(d.setpoint.accel_mps2 < -2.5, "{d:?}");
}
