use super::*;

fn lanes(list: &[u8]) -> LaneSet {
    let mut s = LaneSet::EMPTY;
    for &l in list {
        s.insert(l);
    }
    s
}

fn body(id: u32, x: f64, v: f64, a: f64, lane_list: &[u8]) -> Body {
    Body {
        id,
        x,
        v,
        a,
        lanes: lanes(lane_list),
        changing_lanes: lane_list.len() > 1,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn ttc_headway_and_drac_of_a_leader_by_hand() {
    // Gap 35 - 0 - 5 = 30 m, closing 20 - 15 = 5 m/s.
    let m = measure(&[body(0, 0.0, 20.0, 0.0, &[1]), body(1, 35.0, 15.0, 0.0, &[1])]);
    assert!(close(m.ttc_leader_s.unwrap(), 6.0));
    assert!(close(m.headway_s.unwrap(), 1.5));
    assert!(close(m.drac_mps2.unwrap(), 25.0 / 60.0));
    assert_eq!(m.ttc_follower_s, None);
    // A faster leader: no TTC, no DRAC, the headway remains.
    let m = measure(&[body(0, 0.0, 20.0, 0.0, &[1]), body(1, 35.0, 25.0, 0.0, &[1])]);
    assert_eq!((m.ttc_leader_s, m.drac_mps2), (None, None));
    assert!(close(m.headway_s.unwrap(), 1.5));
}

#[test]
fn neighbours_share_a_lane_and_the_nearest_counts() {
    // The vehicle in the other lane is ignored; of two leaders the nearer one counts.
    let m = measure(&[
        body(0, 0.0, 20.0, 0.0, &[2]),
        body(1, 8.0, 0.0, 0.0, &[1]),
        body(2, 45.0, 10.0, 0.0, &[2]),
        body(3, 25.0, 15.0, 0.0, &[2]),
        body(4, -20.0, 30.0, 0.0, &[2]),
    ]);
    // Leader SV3: gap 20, closing 5; follower SV4: gap 15, closing 10.
    assert!(close(m.ttc_leader_s.unwrap(), 4.0));
    assert!(close(m.ttc_follower_s.unwrap(), 1.5));
    assert!(close(m.ttc_s().unwrap(), 1.5));
    // Changing lanes, the ego occupies both lanes: SV1 (gap 3, closing 20) becomes the leader.
    let m = measure(&[body(0, 0.0, 20.0, 0.0, &[1, 2]), body(1, 8.0, 0.0, 0.0, &[1])]);
    assert!(close(m.ttc_leader_s.unwrap(), 0.15));
    assert!(close(m.drac_mps2.unwrap(), 400.0 / 6.0));
}

#[test]
fn accumulator_sums_an_episode_by_hand() {
    let ego = |v: f64, a: f64| body(0, 0.0, v, a, &[1]);
    let mut acc = SafetyAccumulator::new(0.1, 0.0);
    // 1: leader gap 30, closing 5 -> TTC 6, headway 1.5, DRAC 25/60.
    acc.observe(&[ego(20.0, -3.0), body(1, 35.0, 15.0, 0.0, &[1])]);
    // 2: gap 10, closing 10 -> TTC 1, headway 0.5, DRAC 5.
    acc.observe(&[ego(20.0, -3.0), body(1, 15.0, 10.0, 0.0, &[1])]);
    // 3: faster leader at gap 10 -> headway 0.5, no TTC.
    acc.observe(&[ego(20.0, 0.0), body(1, 15.0, 25.0, 0.0, &[1])]);
    // 4: follower gap 15 closing 10 -> TTC 1.5; leader gap 30 at equal speed -> headway 1.5.
    acc.observe(&[
        ego(20.0, -2.5),
        body(1, 35.0, 20.0, 0.0, &[1]),
        body(2, -20.0, 30.0, 0.0, &[1]),
    ]);
    // 5: the only other vehicle is in another lane.
    acc.observe(&[ego(12.0, 1.0), body(1, 10.0, 2.0, 0.0, &[2])]);
    let s = acc.summary();
    assert_eq!(s.steps, 5);
    assert!(close(s.min_ttc_s.unwrap(), 1.0));
    assert_eq!((s.ttc_below_3s_steps, s.headway_below_1s_steps), (2, 2));
    assert!(close(s.ttc_below_3s_share, 0.4) && close(s.headway_below_1s_share, 0.4));
    assert!(close(s.max_drac_mps2, 5.0));
    // Accelerations -3, -3, 0, -2.5, 1: two runs at or below -2.5.
    assert_eq!(s.hard_braking_events, 2);
    // Jerks -30, 0, 30, -25, 35 m/s^3.
    assert!(close(s.jerk_max_abs_mps3, 35.0));
    assert!(close(s.jerk_rms_mps3, (3650.0f64 / 5.0).sqrt()));
    assert!(close(s.min_speed_mps, 12.0));
}

#[test]
fn collision_split_by_who_moved() {
    let ego_keeping = body(0, 0.0, 20.0, 0.0, &[1]);
    let ego_changing = body(0, 0.0, 20.0, 0.0, &[1, 2]);
    let ahead_keeping = body(1, 4.0, 10.0, 0.0, &[1]);
    let ahead_cutting_in = body(1, 4.0, 10.0, 0.0, &[1, 2]);
    let behind = body(2, -4.0, 30.0, 0.0, &[1]);
    use EgoCollisionKind::*;
    assert_eq!(classify_ego_collision(&ego_keeping, &ahead_keeping), EgoAtFault);
    assert_eq!(classify_ego_collision(&ego_changing, &ahead_cutting_in), EgoAtFault);
    assert_eq!(classify_ego_collision(&ego_changing, &behind), EgoAtFault);
    assert_eq!(classify_ego_collision(&ego_keeping, &ahead_cutting_in), EgoHitInLane);
    assert_eq!(classify_ego_collision(&ego_keeping, &behind), EgoHitInLane);
}

#[test]
fn percentiles_treat_never_closing_as_infinite() {
    let v = [Some(4.0), None, Some(1.0), Some(2.0)];
    assert_eq!(ttc_percentile(&v, 0.0), Some(1.0));
    assert_eq!(ttc_percentile(&v, 0.05), Some(1.0));
    assert_eq!(ttc_percentile(&v, 0.5), Some(2.0));
    assert_eq!(ttc_percentile(&v, 0.75), Some(4.0));
    assert_eq!(ttc_percentile(&v, 1.0), None);
    assert_eq!(ttc_percentile(&[], 0.5), None);
}

#[test]
fn group_pools_steps_and_takes_extremes() {
    let a = SafetySummary {
        steps: 300,
        min_ttc_s: Some(2.0),
        ttc_below_3s_steps: 30,
        headway_below_1s_steps: 60,
        max_drac_mps2: 1.0,
        hard_braking_events: 2,
        jerk_rms_mps3: 3.0,
        jerk_max_abs_mps3: 9.0,
        min_speed_mps: 10.0,
        ..SafetySummary::default()
    };
    let b = SafetySummary {
        steps: 100,
        min_ttc_s: None,
        ttc_below_3s_steps: 10,
        headway_below_1s_steps: 0,
        max_drac_mps2: 4.0,
        hard_braking_events: 1,
        jerk_rms_mps3: 1.0,
        jerk_max_abs_mps3: 2.0,
        min_speed_mps: 7.0,
        ..SafetySummary::default()
    };
    let g = GroupSafety::from_episodes([&a, &b].into_iter(), 0.1);
    assert_eq!(g.min_ttc_min_s, Some(2.0));
    assert_eq!(g.min_ttc_p50_s, Some(2.0));
    assert!(close(g.ttc_below_3s_share, 0.1) && close(g.headway_below_1s_share, 0.15));
    assert!(close(g.max_drac_mps2, 4.0));
    // 3 events in 400 steps of 0.1 s = 40 s.
    assert_eq!(g.hard_braking_events, 3);
    assert!(close(g.hard_braking_per_hour, 3.0 * 90.0));
    assert!(close(g.jerk_rms_mps3, ((9.0 * 300.0 + 100.0) / 400.0f64).sqrt()));
    assert!(close(g.jerk_max_abs_mps3, 9.0) && close(g.min_speed_mps, 7.0));
}

#[test]
fn a_lane_changing_ego_follows_the_leader_of_both_lanes() {
    use traffic::{EgoCommand, EgoMode, Road, Scenario, SimParams, VehicleInit};
    let init = |x, lane, v| VehicleInit {
        x,
        lane,
        v,
        desired_speed: v,
    };
    let scenario = Scenario {
        road: Road::new(2, 40.0).unwrap(),
        ego: init(0.0, 2, 20.0),
        svs: vec![init(40.0, 1, 15.0)],
    };
    let mut world = World::new(&scenario, &SimParams::default(), EgoMode::Commanded, 1).unwrap();
    world.step();
    assert_eq!(
        measure(&Body::all(&world)).ttc_leader_s,
        None,
        "SV1 is in the other lane"
    );
    world
        .set_ego_command(EgoCommand {
            target_lane: 1,
            beta: 0,
        })
        .unwrap();
    world.step();
    let bodies = Body::all(&world);
    assert!(bodies[0].changing_lanes && bodies[0].lanes.contains(1) && bodies[0].lanes.contains(2));
    let (ego, sv) = (world.ego(), world.vehicle(1).unwrap());
    let expected = (sv.x - ego.x - VEHICLE_LENGTH) / (ego.v - sv.v);
    assert!(close(measure(&bodies).ttc_leader_s.unwrap(), expected));
}
