//! Pure model functions: road geometry, IDM, MOBIL, lateral profile, jerk limiter, rectangles.

use traffic::*;

const EPS: f64 = 1e-9;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-6
}

// ---------- road ----------

#[test]
fn lane_centres_put_lane_one_leftmost() {
    let road = Road::new(3, 30.0).unwrap();
    // y = (n - i) * 4
    assert_eq!(road.lane_centre(1), 8.0);
    assert_eq!(road.lane_centre(2), 4.0);
    assert_eq!(road.lane_centre(3), 0.0);
    assert_eq!(road.lane_of(7.9), 1);
    assert_eq!(road.lane_of(5.0), 2);
    assert_eq!(road.lane_of(-3.0), 3); // clamped to the road
    assert_eq!(road.lane_of(20.0), 1);
}

#[test]
fn lane_counts_outside_two_to_five_are_rejected() {
    assert_eq!(Road::new(1, 30.0), Err(SimError::InvalidLaneCount(1)));
    assert_eq!(Road::new(6, 30.0), Err(SimError::InvalidLaneCount(6)));
    for n in 2..=5 {
        assert!(Road::new(n, 30.0).is_ok());
    }
}

#[test]
fn off_centre_vehicles_occupy_two_lanes() {
    let road = Road::new(3, 30.0).unwrap();
    let set = |y: f64| road.lanes_occupied(y).iter().collect::<Vec<_>>();
    assert_eq!(set(4.0), vec![2]);
    assert_eq!(set(4.1), vec![2]); // within 0.1 m: still one lane
    assert_eq!(set(4.2), vec![1, 2]); // leaning left
    assert_eq!(set(3.8), vec![2, 3]); // leaning right
    assert_eq!(set(8.5), vec![1]); // no lane 0 to lean into
    assert_eq!(set(6.0), vec![1, 2]); // on the lane line
}

// ---------- IDM (d0 = 2, T = 1.5, a = 1.5, b = 2, delta = 4; 2 sqrt(ab) = 3.4641016) ----------

#[test]
fn idm_free_road() {
    // a = 1.5 * (1 - (20/25)^4) = 1.5 * (1 - 0.4096) = 0.8856
    let a = idm_acceleration(20.0, 25.0, f64::INFINITY, 0.0, &IdmParams::default());
    assert!(close(a, 0.8856), "{a}");
    // At the desired speed the free-road acceleration vanishes.
    let a = idm_acceleration(25.0, 25.0, f64::INFINITY, 0.0, &IdmParams::default());
    assert!(a.abs() < EPS);
}

#[test]
fn idm_following_at_equal_speed() {
    // s* = 2 + 20 * 1.5 = 32; (32/50)^2 = 0.4096
    // a = 1.5 * (1 - 0.4096 - 0.4096) = 0.2712
    let a = idm_acceleration(20.0, 25.0, 50.0, 0.0, &IdmParams::default());
    assert!(close(a, 0.2712), "{a}");
}

#[test]
fn idm_closing_in() {
    // s* = 2 + 30 + 20 * 5 / 3.4641016 = 60.867513; (60.867513/40)^2 = 2.3155339
    // (20/30)^4 = 0.1975309; a = 1.5 * (1 - 0.1975309 - 2.3155339) = -2.2695971
    let a = idm_acceleration(20.0, 30.0, 40.0, 5.0, &IdmParams::default());
    assert!(close(a, -2.2695971), "{a}");
}

#[test]
fn idm_dynamic_term_never_below_standstill_gap() {
    // Leader 10 m/s faster: vT + v dv / (2 sqrt(ab)) = 15 - 28.87 < 0, so s* = d0 = 2.
    // (2/20)^2 = 0.01; (10/30)^4 = 0.0123457; a = 1.5 * (1 - 0.0123457 - 0.01) = 1.4664815
    let a = idm_acceleration(10.0, 30.0, 20.0, -10.0, &IdmParams::default());
    assert!(close(a, 1.4664815), "{a}");
    // Standing at exactly d0 behind a standing leader: 1.5 * (1 - 0 - 1) = 0.
    let a = idm_acceleration(0.0, 10.0, 2.0, 0.0, &IdmParams::default());
    assert!(a.abs() < EPS, "{a}");
}

#[test]
fn idm_is_clamped_to_physical_braking() {
    // s* = 2 + 45 + 300 / 3.4641 = 133.6; (133.6/5)^2 = 714 -> raw a = -1070, clamped to -9.
    let a = idm_acceleration(30.0, 30.0, 5.0, 10.0, &IdmParams::default());
    assert_eq!(a, -9.0);
    // Overlap: full braking.
    assert_eq!(idm_acceleration(10.0, 30.0, -1.0, 0.0, &IdmParams::default()), -9.0);
    // Far below the desired speed the output saturates at a_max: 1.5 * (1 - 0) = 1.5.
    let a = idm_acceleration(0.0, 30.0, f64::INFINITY, 0.0, &IdmParams::default());
    assert_eq!(a, 1.5);
}

// ---------- MOBIL (p = 0.2, a_th = 0.1, b_safe = 4) ----------
// All vehicles drive v = 25 m/s with desired speed 30 m/s: free-road IDM is
// 1.5 * (1 - (25/30)^4) = 1.5 * (1 - 0.4822531) = 0.7766204, and s*(dv = 0) = 2 + 37.5 = 39.5.

fn idm(v: f64, v0: f64, gap: f64, dv: f64) -> f64 {
    idm_acceleration(v, v0, gap, dv, &IdmParams::default())
}

#[test]
fn mobil_accepts_beneficial_safe_change() {
    // c stuck 30 m behind a 20 m/s leader: s* = 39.5 + 25*5/3.4641 = 75.584;
    // (75.584/30)^2 = 6.34778; a_c = 1.5 * (1 - 0.48225 - 6.34778) = -8.745047.
    let a_c = idm(25.0, 30.0, 30.0, 5.0);
    assert!(close(a_c, -8.745047), "{a_c}");
    // Target lane free ahead: a~_c = 0.7766204.
    let a_c_new = idm(25.0, 30.0, f64::INFINITY, 0.0);
    // New follower 40 m behind, currently free: a_n = 0.7766204;
    // behind c: (39.5/40)^2 = 0.97516, a~_n = 1.5 * (1 - 0.48225 - 0.97516) = -0.686114.
    let a_n = idm(25.0, 30.0, f64::INFINITY, 0.0);
    let a_n_new = idm(25.0, 30.0, 40.0, 0.0);
    assert!(close(a_n_new, -0.686114), "{a_n_new}");
    let d = mobil_evaluate(
        &MobilInput {
            a_c,
            a_c_new,
            a_n,
            a_n_new,
            gap_new_follower: Some(40.0),
            ..Default::default()
        },
        &MobilParams::default(),
    );
    // incentive = (0.77662 + 8.74505) + 0.2 * (-0.68611 - 0.77662) = 9.521667 - 0.292547 = 9.229120
    assert!(close(d.incentive, 9.229120), "{}", d.incentive);
    assert!(d.safe && d.beneficial && d.accepted());
}

#[test]
fn mobil_rejects_change_forcing_new_follower_to_brake_hard() {
    // Same strong incentive, but the new follower is only 8 m behind:
    // (39.5/8)^2 = 24.38 -> a~_n clamps to -9 < -b_safe = -4.
    let a_n_new = idm(25.0, 30.0, 8.0, 0.0);
    assert_eq!(a_n_new, -9.0);
    let d = mobil_evaluate(
        &MobilInput {
            a_c: idm(25.0, 30.0, 30.0, 5.0),
            a_c_new: idm(25.0, 30.0, f64::INFINITY, 0.0),
            a_n: idm(25.0, 30.0, f64::INFINITY, 0.0),
            a_n_new,
            gap_new_follower: Some(8.0),
            ..Default::default()
        },
        &MobilParams::default(),
    );
    assert!(d.beneficial);
    assert!(!d.safe);
    assert!(!d.accepted());
}

#[test]
fn mobil_rejects_overlapping_gap_even_without_braking() {
    let d = mobil_evaluate(
        &MobilInput {
            a_c: -2.0,
            a_c_new: 1.0,
            gap_new_leader: Some(-0.5),
            ..Default::default()
        },
        &MobilParams::default(),
    );
    assert!(d.beneficial && !d.safe);
}

#[test]
fn mobil_rejects_gain_below_threshold() {
    // Leader 100 m ahead at equal speed: (39.5/100)^2 = 0.156025,
    // a_c = 1.5 * (1 - 0.482253 - 0.156025) = 0.542583; a~_c = 0.776620 (gain 0.234037).
    // New follower 50 m behind: (39.5/50)^2 = 0.6241, a~_n = 1.5 * (1 - 0.482253 - 0.6241)
    // = -0.159530; a_n = 0.776620.
    // incentive = 0.234037 + 0.2 * (-0.159530 - 0.776620) = 0.234037 - 0.187230 = 0.046807 < 0.1
    let a_c = idm(25.0, 30.0, 100.0, 0.0);
    assert!(close(a_c, 0.542583), "{a_c}");
    let d = mobil_evaluate(
        &MobilInput {
            a_c,
            a_c_new: idm(25.0, 30.0, f64::INFINITY, 0.0),
            a_n: idm(25.0, 30.0, f64::INFINITY, 0.0),
            a_n_new: idm(25.0, 30.0, 50.0, 0.0),
            gap_new_follower: Some(50.0),
            ..Default::default()
        },
        &MobilParams::default(),
    );
    assert!(close(d.incentive, 0.046807), "{}", d.incentive);
    assert!(d.safe);
    assert!(!d.beneficial && !d.accepted());
    // A selfish driver (p = 0) would go: 0.234 > 0.1.
    let selfish = MobilParams {
        politeness: 0.0,
        ..MobilParams::default()
    };
    let d2 = mobil_evaluate(
        &MobilInput {
            a_c,
            a_c_new: idm(25.0, 30.0, f64::INFINITY, 0.0),
            a_n: idm(25.0, 30.0, f64::INFINITY, 0.0),
            a_n_new: idm(25.0, 30.0, 50.0, 0.0),
            gap_new_follower: Some(50.0),
            ..Default::default()
        },
        &selfish,
    );
    assert!(d2.accepted());
}

// ---------- lateral profile ----------

#[test]
fn smooth_profile_is_symmetric_with_flat_ends() {
    assert_eq!(smooth_profile(0.0), 0.0);
    assert_eq!(smooth_profile(1.0), 1.0);
    assert!((smooth_profile(0.5) - 0.5).abs() < EPS);
    for k in 0..=100 {
        let s = f64::from(k) / 100.0;
        assert!((smooth_profile(s) + smooth_profile(1.0 - s) - 1.0).abs() < 1e-12);
    }
    // Zero slope at both ends: finite differences vanish quadratically.
    let h = 1e-4;
    assert!(smooth_profile(h) / h < 1e-6);
    assert!((1.0 - smooth_profile(1.0 - h)) / h < 1e-6);
}

// ---------- jerk limiter ----------

#[test]
fn jerk_limiter_steps_at_most_jerk_dt() {
    // jerk 15, dt 0.1 -> at most 1.5 m/s^2 change per step; from 0 towards -3 takes 2 steps.
    let a1 = jerk_limited_acceleration(20.0, 40.0, 0.0, -3.0, 15.0, 0.1);
    assert!(close(a1, -1.5));
    let a2 = jerk_limited_acceleration(20.0, 40.0, a1, -3.0, 15.0, 0.1);
    assert!(close(a2, -3.0));
    // At the speed limit, acceleration requests are ignored.
    assert_eq!(jerk_limited_acceleration(40.0, 40.0, 0.0, 1.5, 15.0, 0.1), 0.0);
    // Near standstill braking is eased off so that a reaches 0 exactly as v reaches 0.
    // v = 0.3, a = -3: ramping -3, -1.5, 0 would remove 0.45 m/s > 0.3. The largest feasible
    // braking a satisfies 0.1 * (a + (a - 1.5)) = 0.3 -> a = 2.25, i.e. -2.25 now,
    // then v = 0.3 - 0.225 = 0.075 -> 0.1 * a = 0.075 -> a = -0.75, then v = 0 and a = 0.
    let a1 = jerk_limited_acceleration(0.3, 40.0, -3.0, -3.0, 15.0, 0.1);
    assert!(close(a1, -2.25), "{a1}");
    let a2 = jerk_limited_acceleration(0.075, 40.0, a1, -3.0, 15.0, 0.1);
    assert!(close(a2, -0.75), "{a2}");
    let a3 = jerk_limited_acceleration(0.0, 40.0, a2, -3.0, 15.0, 0.1);
    assert_eq!(a3, 0.0);
}

// ---------- rectangles ----------

#[test]
fn rectangle_overlap_geometry() {
    // 5 x 2 boxes: overlap iff |dx| < 5 and |dy| < 2.
    assert!(rectangles_overlap((0.0, 0.0), (4.9, 0.0)));
    assert!(!rectangles_overlap((0.0, 0.0), (5.0, 0.0))); // bumpers touching
    assert!(!rectangles_overlap((0.0, 0.0), (-5.0, 0.0)));
    assert!(!rectangles_overlap((0.0, 0.0), (0.0, 2.0))); // sides touching
    assert!(rectangles_overlap((0.0, 0.0), (0.0, 1.99)));
    assert!(rectangles_overlap((0.0, 0.0), (-4.9, -1.9)));
    assert!(!rectangles_overlap((0.0, 0.0), (0.0, 4.0))); // adjacent lane centres
    assert!(!rectangles_overlap((0.0, 0.0), (4.9, 2.1)));
}
