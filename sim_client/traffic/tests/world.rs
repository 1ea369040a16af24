//! World-level behaviour: lane-change timing, collisions, ego control, SV behaviour, perception.

use traffic::*;

const EPS: f64 = 1e-9;

fn init(x: f64, lane: u8, v: f64, desired_speed: f64) -> VehicleInit {
    VehicleInit {
        x,
        lane,
        v,
        desired_speed,
    }
}

fn scene(lanes: u8, ego: VehicleInit, svs: Vec<VehicleInit>) -> Scenario {
    Scenario {
        road: Road::new(lanes, 40.0).unwrap(),
        ego,
        svs,
    }
}

/// Deterministic SVs: no random switches.
fn calm() -> SimParams {
    SimParams {
        sv: SvBehaviour::deterministic(),
        ..SimParams::default()
    }
}

#[test]
fn ego_lane_change_reaches_target_at_t_lc_and_is_halfway_at_half() {
    let s = scene(2, init(0.0, 2, 20.0, 25.0), vec![]);
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    w.set_ego_command(EgoCommand {
        target_lane: 1,
        beta: 0,
    })
    .unwrap();
    let mut ys = vec![w.ego().y];
    for _ in 0..30 {
        w.step();
        ys.push(w.ego().y);
    }
    // Lane 2 centre y = 0, lane 1 centre y = 4; T_lc = 3 s = 30 steps.
    assert_eq!(ys[0], 0.0);
    assert!((ys[15] - 2.0).abs() < EPS, "halfway at T_lc/2: {}", ys[15]);
    assert!(ys[29] < 4.0);
    assert_eq!(ys[30], 4.0);
    assert_eq!(w.ego().lane, 1);
    assert!(w.ego().lane_change.is_none());
    // Symmetric profile and monotone motion.
    for k in 0..=30 {
        assert!((ys[k] + ys[30 - k] - 4.0).abs() < 1e-9);
    }
    assert!(ys.windows(2).all(|p| p[1] >= p[0]));
    // Smooth start and end: first and last lateral steps are tiny compared to the mean 0.133 m.
    assert!(ys[1] - ys[0] < 0.01 && ys[30] - ys[29] < 0.01);
    // Mid-way the ego occupies both lanes.
    let mid = w.road().lanes_occupied(ys[15]);
    assert!(mid.contains(1) && mid.contains(2));
    // Longitudinal speed untouched by lateral motion.
    assert_eq!(w.ego().v, 20.0);
}

#[test]
fn ego_lane_change_duration_scales_with_distance_and_restarts_mid_way() {
    let s = scene(3, init(0.0, 3, 20.0, 25.0), vec![]);
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    // Two lanes = 8 m -> 6 s = 60 steps.
    w.set_ego_command(EgoCommand {
        target_lane: 1,
        beta: 0,
    })
    .unwrap();
    for _ in 0..59 {
        w.step();
    }
    assert!(w.ego().y < 8.0);
    w.step();
    assert_eq!(w.ego().y, 8.0);
    assert_eq!(w.ego().lane, 1);

    // Go back towards lane 2, abort after 10 steps towards lane 1 again.
    w.set_ego_command(EgoCommand {
        target_lane: 2,
        beta: 0,
    })
    .unwrap();
    for _ in 0..10 {
        w.step();
    }
    let y_abort = w.ego().y;
    assert!(y_abort < 8.0 && y_abort > 4.0);
    w.set_ego_command(EgoCommand {
        target_lane: 1,
        beta: 0,
    })
    .unwrap();
    // Restart from the current y, duration 3 s * dy / 4 m (>= 0.5 s).
    let lc = w.ego().lane_change.unwrap();
    assert_eq!(lc.from_y, y_abort);
    let expected = (3.0 * (8.0 - y_abort) / 4.0).max(0.5);
    assert!((lc.duration - expected).abs() < EPS);
    w.step();
    assert!(w.ego().y >= y_abort, "no lateral jump back");
    let steps = (expected / 0.1).ceil() as usize;
    for _ in 1..steps {
        w.step();
    }
    assert_eq!(w.ego().y, 8.0);
    // Same target again: no new manoeuvre.
    w.set_ego_command(EgoCommand {
        target_lane: 1,
        beta: 1,
    })
    .unwrap();
    assert!(w.ego().lane_change.is_none());
}

#[test]
fn lateral_overlap_during_lane_change_is_a_collision() {
    // SV alongside in lane 1, 3 m ahead, same speed, cruising at its desired speed.
    let s = scene(2, init(0.0, 2, 20.0, 20.0), vec![init(3.0, 1, 20.0, 20.0)]);
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    w.set_ego_command(EgoCommand {
        target_lane: 1,
        beta: 0,
    })
    .unwrap();
    // dy = 4 - y_ego; overlap iff dy < 2 iff y_ego > 2, i.e. after the halfway point (step 15).
    for k in 1..=15 {
        assert!(w.step().is_empty(), "no collision at step {k}");
    }
    let c = w.step();
    assert_eq!(
        c,
        vec![Collision {
            a: 0,
            b: 1,
            involves_ego: true,
            first_contact: true
        }]
    );
    // The simulation keeps going and keeps reporting the ongoing overlap.
    let c = w.step();
    assert_eq!(c.len(), 1);
    assert!(!c[0].first_contact);
}

#[test]
fn rear_end_collision_is_reported_and_simulation_continues() {
    // Commanded ego at 30 m/s closing on an SV at 10 m/s 20 m ahead (bumper gap 15 m).
    let s = scene(2, init(0.0, 1, 30.0, 30.0), vec![init(20.0, 1, 10.0, 10.0)]);
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    let mut hit = None;
    for k in 0..30 {
        let c = w.step();
        if hit.is_none() && !c.is_empty() {
            hit = Some(k);
            assert!(c[0].involves_ego && c[0].first_contact);
        }
    }
    // Closing speed 20 m/s eats 15 m within 0.75 s: the overlap starts at step index 7 or 8.
    let k = hit.expect("collision");
    assert!((7..=8).contains(&k), "{k}");
    assert!((w.time() - 3.0).abs() < EPS);
}

#[test]
fn sv_collision_flags_do_not_involve_ego() {
    // Two SVs overlapping from the start are refused...
    let s = scene(
        2,
        init(0.0, 2, 10.0, 10.0),
        vec![init(100.0, 1, 10.0, 10.0), init(103.0, 1, 10.0, 10.0)],
    );
    assert_eq!(
        World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap_err(),
        SimError::InitialOverlap { a: 1, b: 2 }
    );
    // ...but two SVs closing at 8 m/s from 1 m (bumper) apart cannot stop in time.
    let s = scene(
        2,
        init(0.0, 2, 10.0, 10.0),
        vec![init(100.0, 1, 18.0, 18.0), init(106.0, 1, 10.0, 10.0)],
    );
    // Braking at -9 m/s^2 needs 8^2 / 18 = 3.6 m of relative travel.
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    let c = (0..10).map(|_| w.step()).find(|c| !c.is_empty()).expect("collision");
    assert_eq!(c.len(), 1);
    assert_eq!((c[0].a, c[0].b, c[0].involves_ego), (1, 2, false));
}

#[test]
fn ego_jerk_and_speed_bounds_hold_through_acceleration_and_braking() {
    let mut s = scene(2, init(0.0, 2, 16.0, 25.0), vec![]);
    s.road.speed_limit = 20.0;
    let p = calm();
    let mut w = World::new(&s, &p, EgoMode::Commanded, 1).unwrap();
    let da_max = p.jerk_max * p.dt + 1e-9;
    let mut a_prev = w.ego().a;
    let mut check = |w: &World| {
        let e = w.ego();
        assert!((e.a - a_prev).abs() <= da_max, "jerk: {} -> {}", a_prev, e.a);
        assert!(e.v >= 0.0 && e.v <= 20.0 + 1e-12, "speed {}", e.v);
        a_prev = e.a;
    };
    w.set_ego_command(EgoCommand {
        target_lane: 2,
        beta: 1,
    })
    .unwrap();
    let mut reached_accel = false;
    for _ in 0..60 {
        w.step();
        reached_accel |= (w.ego().a - 1.5).abs() < EPS;
        check(&w);
    }
    assert!(reached_accel);
    assert!((w.ego().v - 20.0).abs() < 1e-6, "speed limit reached");
    assert!(w.ego().a.abs() < 1e-6, "acceleration 0 at the limit");
    w.set_ego_command(EgoCommand {
        target_lane: 2,
        beta: -1,
    })
    .unwrap();
    let mut reached_decel = false;
    for _ in 0..120 {
        w.step();
        reached_decel |= (w.ego().a + 3.0).abs() < EPS;
        check(&w);
    }
    assert!(reached_decel);
    assert_eq!(w.ego().v, 0.0);
    assert!(w.ego().a.abs() < 1e-6);
    let x_stop = w.ego().x;
    w.step();
    assert_eq!(w.ego().x, x_stop, "a stopped ego does not creep backwards");
}

#[test]
fn ego_braking_to_standstill_respects_jerk_from_any_speed() {
    // The residual speed when braking ends varies with the initial speed; the final
    // ease-off must stay within jerk * dt = 1.5 m/s^2 per step in every case.
    for k in 0..40 {
        let v0 = 5.0 + 0.0137 * f64::from(k);
        let s = scene(2, init(0.0, 2, v0, 25.0), vec![]);
        let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
        w.set_ego_command(EgoCommand {
            target_lane: 2,
            beta: -1,
        })
        .unwrap();
        let mut a_prev = 0.0;
        for _ in 0..40 {
            let v_prev = w.ego().v;
            w.step();
            let e = w.ego();
            assert!((e.a - a_prev).abs() <= 1.5 + 1e-9, "v0 {v0}: {a_prev} -> {}", e.a);
            // No hidden clamping: the reported acceleration is what changed the speed.
            assert!(
                (e.v - (v_prev + e.a * 0.1)).abs() < 1e-9,
                "v0 {v0}: clamped at {v_prev}"
            );
            assert!(e.v >= 0.0);
            a_prev = e.a;
        }
        assert_eq!(w.ego().v, 0.0);
        assert!(w.ego().a.abs() < 1e-9);
    }
}

#[test]
fn ego_command_validation() {
    let s = scene(2, init(0.0, 2, 16.0, 25.0), vec![]);
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    assert_eq!(
        w.set_ego_command(EgoCommand {
            target_lane: 3,
            beta: 0
        }),
        Err(SimError::InvalidLane { lane: 3, lanes: 2 })
    );
    assert_eq!(
        w.set_ego_command(EgoCommand {
            target_lane: 0,
            beta: 0
        }),
        Err(SimError::InvalidLane { lane: 0, lanes: 2 })
    );
    assert_eq!(
        w.set_ego_command(EgoCommand {
            target_lane: 1,
            beta: 2
        }),
        Err(SimError::InvalidBeta(2))
    );
    // Rejected commands leave the state alone.
    assert!(w.ego().lane_change.is_none());
    let mut rule_based = World::new(&s, &calm(), EgoMode::IdmMobil, 1).unwrap();
    assert_eq!(
        rule_based.set_ego_command(EgoCommand {
            target_lane: 1,
            beta: 0
        }),
        Err(SimError::EgoNotCommanded)
    );
}

#[test]
fn world_rejects_bad_inputs() {
    let s = scene(2, init(0.0, 3, 16.0, 25.0), vec![]);
    assert_eq!(
        World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap_err(),
        SimError::InvalidLane { lane: 3, lanes: 2 }
    );
    let mut s = scene(2, init(0.0, 2, 16.0, 25.0), vec![]);
    s.road.lanes = 7;
    assert_eq!(
        World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap_err(),
        SimError::InvalidLaneCount(7)
    );
    let s = scene(2, init(0.0, 2, 16.0, 25.0), vec![]);
    let bad = SimParams {
        decision_period: 0.25,
        ..calm()
    };
    assert!(matches!(
        World::new(&s, &bad, EgoMode::Commanded, 1),
        Err(SimError::InvalidParameter {
            name: "decision_period",
            ..
        })
    ));
}

#[test]
fn sv_changes_to_free_lane_behind_slow_leader() {
    // 3 lanes. SV1 (25 m/s, wants 30) 30 m (bumper) behind SV2 (20 m/s) in lane 2;
    // lanes 1 and 3 are empty, so both changes are equally good and the left one wins.
    let s = scene(
        3,
        init(-500.0, 3, 20.0, 20.0),
        vec![init(100.0, 2, 25.0, 30.0), init(135.0, 2, 20.0, 20.0)],
    );
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    w.step();
    let sv1 = w.vehicle(1).unwrap();
    assert_eq!(sv1.target_lane, 1);
    assert!(sv1.is_changing_lanes());
    for _ in 1..30 {
        w.step();
    }
    let sv1 = w.vehicle(1).unwrap();
    assert_eq!((sv1.lane, sv1.y), (1, 8.0));
    assert!(!sv1.is_changing_lanes());
}

#[test]
fn sv_stays_when_neighbours_block_both_sides() {
    // Same situation, but a vehicle sits 8 m (centre) behind SV1 in both neighbour lanes:
    // 3 m bumper gap -> the new follower would need about -9 m/s^2 > b_safe, so no change.
    let s = scene(
        3,
        init(-500.0, 3, 20.0, 20.0),
        vec![
            init(100.0, 2, 25.0, 30.0),
            init(135.0, 2, 20.0, 20.0),
            init(92.0, 1, 25.0, 30.0),
            init(92.0, 3, 25.0, 30.0),
        ],
    );
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    w.step();
    let sv1 = w.vehicle(1).unwrap();
    assert_eq!(sv1.target_lane, 2);
    assert!(!sv1.is_changing_lanes());
    assert!(sv1.a < -4.0, "it brakes instead: {}", sv1.a);
}

#[test]
fn lane_changer_is_followed_in_both_lanes() {
    // SV1 changes from lane 2 into lane 1 ahead of SV3; SV3 must start reacting at once.
    let s = scene(
        2,
        init(-500.0, 2, 20.0, 20.0),
        vec![
            init(100.0, 2, 25.0, 30.0),
            init(135.0, 2, 20.0, 20.0),
            init(60.0, 1, 25.0, 30.0),
        ],
    );
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    w.step();
    let sv1 = w.vehicle(1).unwrap();
    assert_eq!(sv1.target_lane, 1, "35 m bumper gap is enough");
    // SV3 sees SV1 35 m ahead at equal speed: s* = 39.5, (39.5/35)^2 = 1.2737,
    // a = 1.5 * (1 - 0.48225 - 1.2737) < 0 even though its lane was free before.
    assert!(w.vehicle(3).unwrap().a < 0.0);
}

#[test]
fn sv_longitudinal_modes_follow_hmdp_switches() {
    // p_keep_long = 0: beta switches at every decision instant: 1 -> 0 -> +-1 -> 0 ...
    let p = SimParams {
        sv: SvBehaviour {
            p_keep_long: 0.0,
            p_random_lane_change: 0.0,
            ..SvBehaviour::default()
        },
        ..SimParams::default()
    };
    let s = scene(2, init(-500.0, 2, 10.0, 10.0), vec![init(0.0, 1, 10.0, 30.0)]);
    let mut w = World::new(&s, &p, EgoMode::Commanded, 7).unwrap();
    let free = idm_acceleration(10.0, 30.0, f64::INFINITY, 0.0, &IdmParams::default());
    let mut betas = vec![];
    for k in 0..40 {
        let v_before = w.vehicle(1).unwrap().v;
        w.step();
        let sv = w.vehicle(1).unwrap();
        if k % 4 == 0 {
            betas.push(sv.beta);
        }
        match sv.beta {
            0 => assert_eq!(sv.a, 0.0, "hold speed on a free road"),
            -1 => assert_eq!(sv.a, -1.0, "gentle slowdown"),
            _ => {
                let idm = idm_acceleration(v_before, 30.0, f64::INFINITY, 0.0, &IdmParams::default());
                assert_eq!(sv.a, idm);
            }
        }
    }
    assert!(free > 0.0);
    assert_eq!(betas[0], 0);
    for pair in betas.windows(2) {
        assert_ne!(pair[0], pair[1]);
        assert!((pair[0] - pair[1]).abs() == 1);
    }
    assert!(betas.contains(&1) && betas.contains(&-1));
}

#[test]
fn sv_speed_never_negative() {
    // Always slowing down from a low speed: it must stop at 0, not reverse.
    let p = SimParams {
        sv: SvBehaviour {
            p_keep_long: 0.0,
            p_random_lane_change: 0.0,
            gentle_decel: 1.0,
        },
        ..SimParams::default()
    };
    let s = scene(
        2,
        init(-500.0, 2, 10.0, 10.0),
        vec![
            init(0.0, 1, 0.3, 5.0),
            init(50.0, 1, 2.0, 5.0),
            init(30.0, 2, 0.05, 0.1),
        ],
    );
    let mut w = World::new(&s, &p, EgoMode::Commanded, 3).unwrap();
    let mut xs: Vec<f64> = w.vehicles().iter().map(|v| v.x).collect();
    for _ in 0..600 {
        w.step();
        for (v, x) in w.vehicles().iter().zip(xs.iter_mut()) {
            assert!(v.v >= 0.0, "vehicle {} speed {}", v.id, v.v);
            assert!(v.x >= *x, "vehicle {} moved backwards", v.id);
            *x = v.x;
        }
    }
}

#[test]
fn random_lane_change_happens_only_when_safe() {
    let p = SimParams {
        sv: SvBehaviour {
            p_keep_long: 1.0,
            p_random_lane_change: 1.0,
            ..SvBehaviour::default()
        },
        ..SimParams::default()
    };
    // Alone at its desired speed, MOBIL sees no gain; the random switch still moves it.
    let s = scene(2, init(-500.0, 2, 20.0, 20.0), vec![init(0.0, 1, 20.0, 20.0)]);
    let mut w = World::new(&s, &p, EgoMode::Commanded, 3).unwrap();
    w.step();
    assert_eq!(w.vehicle(1).unwrap().target_lane, 2);
    // With a car right next to it, the attempt is refused.
    let s = scene(
        2,
        init(-500.0, 2, 20.0, 20.0),
        vec![init(0.0, 1, 20.0, 20.0), init(-2.0, 2, 20.0, 20.0)],
    );
    let mut w = World::new(&s, &p, EgoMode::Commanded, 3).unwrap();
    w.step();
    assert_eq!(w.vehicle(1).unwrap().target_lane, 1);
    // Switched off: nothing happens.
    let s = scene(2, init(-500.0, 2, 20.0, 20.0), vec![init(0.0, 1, 20.0, 20.0)]);
    let mut w = World::new(&s, &calm(), EgoMode::Commanded, 3).unwrap();
    for _ in 0..100 {
        w.step();
    }
    assert_eq!(w.vehicle(1).unwrap().lane, 1);
}

#[test]
fn rule_based_ego_overtakes_slow_leader() {
    let s = scene(2, init(0.0, 2, 25.0, 30.0), vec![init(35.0, 2, 20.0, 20.0)]);
    let mut w = World::new(&s, &calm(), EgoMode::IdmMobil, 1).unwrap();
    w.step();
    assert_eq!(w.ego().target_lane, 1);
    for _ in 0..300 {
        assert!(w.step().is_empty());
    }
    assert!(w.ego().x > w.vehicle(1).unwrap().x + 5.0, "ego passed the SV");
}

#[test]
fn perception_reports_kinematics_within_range() {
    let s = scene(
        3,
        init(100.0, 2, 20.0, 28.0),
        vec![
            init(299.0, 1, 20.0, 25.0),  // 199 m ahead: seen
            init(301.0, 3, 20.0, 25.0),  // 201 m ahead: not seen
            init(-99.0, 2, 20.0, 25.0),  // 199 m behind: seen
            init(-101.0, 3, 20.0, 25.0), // 201 m behind: not seen
        ],
    );
    let w = World::new(&s, &calm(), EgoMode::Commanded, 1).unwrap();
    let p = w.perceive();
    assert_eq!(p.time, 0.0);
    assert_eq!(p.road, *w.road());
    assert_eq!(
        p.ego,
        EgoObservation {
            x: 100.0,
            y: 4.0,
            v: 20.0,
            a: 0.0,
            lane: 2,
            target_lane: 2,
            desired_speed: 28.0
        }
    );
    let ids: Vec<u32> = p.svs.iter().map(|s| s.id).collect();
    assert_eq!(ids, vec![1, 3]);
    assert_eq!(
        p.svs[0],
        SvObservation {
            id: 1,
            x: 299.0,
            y: 8.0,
            v: 20.0,
            a: 0.0,
            vy: 0.0
        }
    );
}

#[test]
fn snapshot_round_trip_resumes_identically() {
    let cfg = TrafficConfig::new(3, 8, (25.0, 40.0));
    let s = Scenario::random(&cfg, 11).unwrap();
    let mut a = World::new(&s, &SimParams::default(), EgoMode::IdmMobil, 5).unwrap();
    for _ in 0..150 {
        a.step();
    }
    let json = serde_json::to_string(&a.snapshot()).unwrap();
    let mut b = World::from_snapshot(serde_json::from_str(&json).unwrap()).unwrap();
    assert_eq!(a.snapshot(), b.snapshot());
    for _ in 0..150 {
        assert_eq!(a.step(), b.step());
    }
    assert_eq!(a.snapshot(), b.snapshot());
}
