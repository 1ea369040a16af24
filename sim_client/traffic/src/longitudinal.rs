/// Speed gain (m/s) of applying `a` (> 0) for one step and then ramping down to zero
/// with decrements of `da` per step: `dt * (a + (a - da) + (a - 2da) + ...)` over positive terms.
fn ramp_gain(a: f64, da: f64, dt: f64) -> f64 {
    if a <= 0.0 {
        return 0.0;
    }
    // Number of positive terms a - k*da, k = 0..m-1.
    let m = (a / da).ceil();
    (m * a - da * m * (m - 1.0) / 2.0) * dt
}

/// Largest `a >= 0` whose ramp-down gain fits in `room` (bisection; keeps the feasible bound).
fn max_feasible(room: f64, da: f64, dt: f64) -> f64 {
    if room <= 0.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, room / dt);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if ramp_gain(mid, da, dt) <= room {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Next acceleration of a jerk-limited vehicle that must keep its speed in `[0, v_max]`.
///
/// The acceleration moves from `a_prev` towards `a_target` by at most `jerk * dt`, and is
/// capped so that it can always be ramped back to zero (at the same jerk) before the speed
/// bound is hit: the bound is reached with zero acceleration instead of a jerk spike.
pub fn jerk_limited_acceleration(v: f64, v_max: f64, a_prev: f64, a_target: f64, jerk: f64, dt: f64) -> f64 {
    let da = jerk * dt;
    let upper = max_feasible(v_max - v, da, dt);
    let lower = -max_feasible(v, da, dt);
    let goal = a_target.clamp(lower, upper);
    a_prev + (goal - a_prev).clamp(-da, da)
}
