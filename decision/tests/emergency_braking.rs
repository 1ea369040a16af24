//! An SV ahead that only braking beyond the MPC's range (`ego.max_decel_mps2`) keeps the ego
//! behind: the ego placed fast behind a slow vehicle, as a randomized scene can place it. The
//! fallback then brakes as hard as needed, down to the vehicle's emergency braking
//! (`ego.emergency_decel_mps2`), at once and without a solve; stopping at the planned range
//! is a collision. It leaves room for that vehicle to slow down (`ego.lead_brake_room_mps2`).

mod common;

use common::{ClosedLoop, Vehicle};
use decision::{
    EgoState, Layer, Maneuver, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation, Threat,
};

/// The first decision's statistics, the ego at `v` m/s `gap` m (bumpers) behind an SV holding
/// `v_sv` on a one-lane road.
fn first_stats(config: PlannerConfig, v: f64, gap: f64, v_sv: f64) -> decision::SolveStats {
    let s = Situation {
        road: Road {
            lanes: 1,
            lane_width_m: 3.5,
            speed_limit_mps: 33.33,
        },
        ego: EgoState {
            x_m: 0.0,
            y_m: 0.0,
            v_mps: v,
            desired_speed_mps: 30.0,
            maneuver: Maneuver { lane: 1, beta: 0 },
        },
        svs: vec![SvObservation::new(1, gap + common::LENGTH_M, 0.0, v_sv, 0.0)],
        memory: PlannerMemory::default(),
    };
    Planner::new(config).unwrap().decide(&s).unwrap().stats
}

/// 8 s of closed loop on one lane: the ego at `v` m/s, `gap` m (bumpers) behind a vehicle
/// holding `v_sv`.
fn behind(config: PlannerConfig, v: f64, gap: f64, v_sv: f64) -> common::Trace {
    ClosedLoop {
        config,
        lanes: 1,
        desired_speed_mps: 30.0,
        ego_v_mps: v,
        vehicles: vec![Vehicle::steady(gap + common::LENGTH_M, v_sv)],
        duration_s: 8.0,
    }
    .run()
}

/// The ego at 30 m/s, 32 m behind a vehicle holding 8 m/s: keeping the jam distance takes
/// 22^2 / (2 * 30) = 8.07 m/s^2, beyond the planned 6.
fn fast_behind_slow(config: PlannerConfig) -> common::Trace {
    behind(config, 30.0, 32.0, 8.0)
}

#[test]
fn the_fallback_brakes_beyond_the_planned_range_when_staying_behind_takes_it() {
    // Without the room for the vehicle ahead to slow down (the next test), the braking is the
    // closed form of the closing alone.
    let mut c = PlannerConfig::default();
    c.ego.lead_brake_room_mps2 = 0.0;
    assert!(c.ego.emergency_decel_mps2 < -8.1 && c.ego.max_decel_mps2 > -8.0);
    let trace = fast_behind_slow(c.clone());
    let first = &trace.decisions[0];
    assert_eq!(first.layer, Layer::Fallback, "no plan within the MPC's range is safe");
    let needed = -(22.0_f64.powi(2)) / (2.0 * 30.0);
    assert!((first.accel_mps2 - needed).abs() < 1e-9, "braking {}", first.accel_mps2);
    assert!(trace.least_gap_m > 0.0, "least gap {}", trace.least_gap_m);
    // Behind it at its speed, the nominal MPC answers again.
    assert!(trace.decisions.iter().any(|d| d.layer == Layer::Nominal));
    assert!(trace.strongest_braking() >= c.ego.emergency_decel_mps2);

    // The same with the emergency braking at the planned range's end: a collision.
    let mut planned_only = c.clone();
    planned_only.ego.emergency_decel_mps2 = c.ego.max_decel_mps2;
    let trace = fast_behind_slow(planned_only);
    assert!(trace.strongest_braking() >= c.ego.max_decel_mps2 - 1e-6);
    assert!(trace.least_gap_m < 0.0, "least gap {}", trace.least_gap_m);
}

#[test]
fn the_mpc_is_not_asked_when_its_range_cannot_keep_the_ego_behind() {
    // Without hysteresis the nominal MPC has a plan here: an SV already inside its margin may
    // stay inside for a while (`idm.violation_decay`), and within its 1.2 s horizon braking at
    // -6 m/s^2 looks enough. It is not: 23.3^2 / (2 * 36.8) = 7.38 m/s^2 keeps the jam
    // distance, and the MPC's plan would end in a collision beyond its horizon (least gap
    // -2.3 m without this check).
    let mut c = PlannerConfig::default();
    c.hysteresis.enabled = false;
    let trace = behind(c.clone(), 33.0, 38.8, 9.7);
    assert_eq!(trace.decisions[0].layer, Layer::Fallback);
    assert!(
        trace.decisions[0].accel_mps2 < -7.0,
        "braking {}",
        trace.decisions[0].accel_mps2
    );
    assert!(trace.least_gap_m > 1.5, "least gap {}", trace.least_gap_m);
    // The decision says why: an emergency behind an SV ahead, nothing solved.
    let stats = first_stats(c, 33.0, 38.8, 9.7);
    assert!(stats.emergency);
    assert_eq!(stats.fallback_threat, Some(Threat::Front));
    assert_eq!((stats.rows, stats.nodes, stats.sequences), (0, 0, 0));
}

#[test]
fn within_the_planned_range_the_mpc_decides() {
    // 60 m behind at 30 m/s a vehicle at 14 m/s: 16^2 / (2 * 58) = 2.2 m/s^2 keeps the jam
    // distance, and 30^2 / (2 * (58 + 14^2 / 6)) = 5.0 m/s^2 were it to brake at 3 m/s^2 to a
    // stop: within the MPC's range, no emergency, and the MPC (nominal or relaxed) answers.
    let trace = behind(PlannerConfig::default(), 30.0, 60.0, 14.0);
    assert_ne!(trace.decisions[0].layer, Layer::Fallback);
    assert!(trace.strongest_braking() >= PlannerConfig::default().ego.max_decel_mps2 - 1e-6);
    assert!(!first_stats(PlannerConfig::default(), 30.0, 60.0, 14.0).emergency);
    assert!(trace.least_gap_m > 0.0, "least gap {}", trace.least_gap_m);
}

/// The ego at 30 m/s, `gap` m (bumpers) behind a vehicle at 8 m/s that holds its speed for
/// `t_brake` s, then slows at 3 m/s^2 to a stop; the ego's brakes build up at 15 m/s^3.
fn fast_behind_slowing(config: PlannerConfig, gap: f64, t_brake: f64) -> common::Trace {
    ClosedLoop {
        config,
        lanes: 1,
        desired_speed_mps: 30.0,
        ego_v_mps: 30.0,
        vehicles: vec![Vehicle {
            x_m: gap + common::LENGTH_M,
            v_mps: 8.0,
            accel: Box::new(move |t, _| if t < t_brake { 0.0 } else { -3.0 }),
            speed_bounds: (0.0, f64::INFINITY),
        }],
        duration_s: 10.0,
    }
    .run_jerk_limited(15.0)
}

#[test]
fn the_fallback_keeps_room_for_a_slow_vehicle_ahead_to_slow_down() {
    // Braking just enough behind the vehicle at its present speed (-6.37 m/s^2 from 40 m,
    // -6 from 45 m) leaves no room for it to slow down: without the room the ego hits it in
    // these scenes (least gaps -0.8 to -2.6 m). With the room for it to brake at 3 m/s^2 to a
    // stop, the ego brakes harder at once (-9 and -8.39) and stays about the jam distance
    // behind it.
    let c = PlannerConfig::default();
    assert_eq!(c.ego.lead_brake_room_mps2, 3.0);
    let mut no_room = c.clone();
    no_room.ego.lead_brake_room_mps2 = 0.0;
    for (gap, t_brake) in [(40.0, 1.2), (40.0, 1.6), (45.0, 0.8), (45.0, 1.2), (45.0, 1.6)] {
        let with = fast_behind_slowing(c.clone(), gap, t_brake);
        assert_eq!(with.decisions[0].layer, Layer::Fallback);
        assert!(
            with.decisions[0].accel_mps2 < -8.0,
            "{gap} m, {t_brake} s: braking {}",
            with.decisions[0].accel_mps2
        );
        assert!(
            with.least_gap_m > 1.5,
            "{gap} m, {t_brake} s: least gap {}",
            with.least_gap_m
        );
        let without = fast_behind_slowing(no_room.clone(), gap, t_brake);
        assert!(
            without.decisions[0].accel_mps2 > -6.5,
            "{gap} m, {t_brake} s: braking {}",
            without.decisions[0].accel_mps2
        );
        assert!(
            with.least_gap_m > without.least_gap_m + 2.0,
            "{gap} m, {t_brake} s: least gap {} against {} without the room",
            with.least_gap_m,
            without.least_gap_m
        );
    }
}

/// Whether an answer is an emergency brake, read as a client reads the wire: a fallback
/// (`layer = fallback`) whose set-point brakes beyond the strongest braking the MPC plans
/// (`ego.max_decel_mps2`). docs/protocol.md gives this rule to clients, and
/// `protocol::Decided::is_emergency_brake` reads it.
fn brakes_as_an_emergency_on_the_wire(config: &PlannerConfig, d: &decision::Decision) -> bool {
    d.layer == Layer::Fallback && d.setpoint.accel_mps2 < config.ego.max_decel_mps2
}

#[test]
fn an_emergency_is_what_the_wire_shows_as_a_fallback_braking_beyond_the_planned_range() {
    // The ego fast behind slow, braking or stopped vehicles at every distance, with and
    // without hysteresis and the room for the vehicle ahead to slow down, and the paper classes'
    // random situations: the in-process flag and the wire's rule agree on every decision.
    let mut emergencies = 0;
    let mut fallbacks = 0;
    let mut configs = vec![PlannerConfig::default()];
    configs.push({
        let mut c = PlannerConfig::default();
        c.hysteresis.enabled = false;
        c
    });
    configs.push({
        let mut c = PlannerConfig::default();
        c.ego.lead_brake_room_mps2 = 0.0;
        c
    });
    for config in &configs {
        let mut planner = Planner::new(config.clone()).unwrap();
        let mut check = |s: &Situation| {
            let d = planner.decide(s).unwrap();
            assert_eq!(
                d.stats.emergency,
                brakes_as_an_emergency_on_the_wire(config, &d),
                "{s:?}: {d:?}"
            );
            emergencies += usize::from(d.stats.emergency);
            fallbacks += usize::from(d.layer == Layer::Fallback);
        };
        for v in [10.0, 20.0, 30.0, 36.0] {
            for gap in [1.0, 3.0, 6.0, 12.0, 20.0, 30.0, 45.0, 60.0, 90.0] {
                for v_sv in [0.0, 5.0, 10.0, 20.0] {
                    for a_sv in [0.0, -3.0, -6.0] {
                        if v_sv == 0.0 && a_sv != 0.0 {
                            continue; // a stopped vehicle does not brake
                        }
                        let sv = SvObservation::new(1, gap + common::LENGTH_M, 0.0, v_sv, a_sv);
                        check(&Situation {
                            road: Road {
                                lanes: 2,
                                lane_width_m: 3.5,
                                speed_limit_mps: 40.0,
                            },
                            ego: EgoState {
                                x_m: 0.0,
                                y_m: 0.0,
                                v_mps: v,
                                desired_speed_mps: 33.0,
                                maneuver: Maneuver { lane: 1, beta: 0 },
                            },
                            svs: vec![sv, SvObservation::new(2, gap * 0.5, 3.5, v_sv, 0.0)],
                            memory: PlannerMemory::default(),
                        });
                    }
                }
            }
        }
        let mut generator = decision::corpus::SituationGenerator::new(48);
        for class in decision::corpus::paper_classes() {
            for _ in 0..20 {
                check(&generator.situation(config, &class));
            }
        }
    }
    // Both sides of the rule occur: emergencies, and fallbacks that are not.
    assert!(emergencies > 50, "{emergencies} emergencies");
    assert!(
        fallbacks > emergencies,
        "{fallbacks} fallbacks, {emergencies} emergencies"
    );
}
