//! The ego is one vehicle whatever drives it: the IDM + MOBIL baseline and a commanded ego
//! share the jerk bound and the speed bounds, so a comparison between drivers compares
//! decisions, not vehicles.

use traffic::*;

fn init(x: f64, lane: u8, v: f64, desired_speed: f64) -> VehicleInit {
    VehicleInit {
        x,
        lane,
        v,
        desired_speed,
    }
}

/// The ego at 30 m/s 75 m behind an SV at 10 m/s, an SV beside it keeping it in its lane.
fn slow_ahead() -> Scenario {
    Scenario {
        road: Road::new(2, 40.0).unwrap(),
        ego: init(0.0, 1, 30.0, 30.0),
        svs: vec![init(80.0, 1, 10.0, 10.0), init(0.0, 2, 30.0, 30.0)],
    }
}

fn calm() -> SimParams {
    SimParams {
        sv: SvBehaviour::deterministic(),
        ..SimParams::default()
    }
}

/// The ego's (acceleration, speed) after each of `steps` steps.
fn trace(w: &mut World, steps: usize) -> Vec<(f64, f64)> {
    (0..steps)
        .map(|_| {
            w.step();
            (w.ego().a, w.ego().v)
        })
        .collect()
}

#[test]
fn idm_mobil_ego_brakes_within_the_jerk_bound() {
    let p = calm();
    let s = slow_ahead();
    // The scene asks for full braking at once: without a jerk bound the first step would be
    // the IDM's a_min.
    let gap = 80.0 - VEHICLE_LENGTH;
    assert_eq!(idm_acceleration(30.0, 30.0, gap, 20.0, &p.idm), p.idm.a_min);
    let mut w = World::new(&s, &p, EgoMode::IdmMobil, 1).unwrap();
    let steps = trace(&mut w, 60);
    let da_max = p.jerk_max * p.dt + 1e-9;
    let mut previous = (0.0, 30.0);
    for (k, &(a, v)) in steps.iter().enumerate() {
        assert!((a - previous.0).abs() <= da_max, "step {k}: {} -> {a}", previous.0);
        assert!((0.0..=30.0 + 1e-12).contains(&v), "step {k}: speed {v}");
        // The reported acceleration is what changed the speed (no hidden clamp).
        assert!(
            (v - (previous.1 + a * p.dt)).abs() < 1e-9,
            "step {k}: {previous:?} -> {a}, {v}"
        );
        previous = (a, v);
    }
    assert!(steps.iter().any(|&(a, _)| a == p.idm.a_min), "reaches full braking");
}

#[test]
fn idm_mobil_ego_and_commanded_ego_brake_alike() {
    // While the IDM asks for full braking, the IDM + MOBIL ego follows the same acceleration
    // profile as a commanded ego given the same set-point: one vehicle, two drivers.
    let p = calm();
    let s = slow_ahead();
    let mut idm = World::new(&s, &p, EgoMode::IdmMobil, 1).unwrap();
    let mut commanded = World::new(&s, &p, EgoMode::Commanded, 1).unwrap();
    let hold = EgoCommand {
        target_lane: 1,
        beta: -1,
    };
    commanded.set_ego_command_with_accel(hold, p.idm.a_min).unwrap();
    let ramp = (-p.idm.a_min / (p.jerk_max * p.dt)).ceil() as usize;
    let a = trace(&mut idm, ramp + 2);
    let b = trace(&mut commanded, ramp + 2);
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        assert!(
            (x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9,
            "step {k}: {x:?} against {y:?}"
        );
    }
    assert_eq!(a[ramp].0, p.idm.a_min);
}

#[test]
fn idm_mobil_ego_keeps_the_speed_limit_of_the_commanded_ego() {
    // Desired 45 m/s on a road limited to 40: the IDM asks for more at 40, the vehicle eases
    // its acceleration to 0 at the limit (jerk-limited) and never exceeds it.
    let p = calm();
    let s = Scenario {
        road: Road::new(2, 40.0).unwrap(),
        ego: init(0.0, 1, 36.0, 45.0),
        svs: vec![],
    };
    let mut w = World::new(&s, &p, EgoMode::IdmMobil, 1).unwrap();
    let steps = trace(&mut w, 100);
    let da_max = p.jerk_max * p.dt + 1e-9;
    let mut previous = 0.0;
    for (k, &(a, v)) in steps.iter().enumerate() {
        assert!(v <= 40.0 + 1e-12, "step {k}: speed {v}");
        assert!((a - previous).abs() <= da_max, "step {k}: {previous} -> {a}");
        previous = a;
    }
    let (a, v) = steps[steps.len() - 1];
    assert!((v - 40.0).abs() < 1e-6 && a.abs() < 1e-6, "ends at {v} m/s, {a} m/s^2");
}
