//! The braking that keeps the ego behind a braking leader: the least constant deceleration
//! with which the gap never falls below the jam distance, the leader braking on at its
//! measured deceleration until it stops (or holding its speed when it does not brake).
//!
//! The IDM margin is a gap to settle at, not a limit: the violation allowance lets the ego
//! recover it comfortably. That must never mean braking less than this, or a leader braking
//! hard is followed at a comfortable deceleration into its bumper.

/// Least constant deceleration (m/s^2, >= 0) of an ego at `v_ego` keeping at least `jam_m`
/// behind a leader `gap_m` ahead at `v_leader` accelerating at `a_leader` (a negative value
/// brakes it to a stop; otherwise it holds its speed). A leader already closer than `jam_m`
/// (a cut-in at the bumper) is to come no closer than it is. Infinite when no braking does
/// that (closer than `jam_m` and closing).
pub fn stopping_decel(gap_m: f64, jam_m: f64, v_ego: f64, v_leader: f64, a_leader: f64) -> f64 {
    let (v_e, v_l) = (v_ego.max(0.0), v_leader.max(0.0));
    let b_l = (-a_leader).max(0.0);
    let jam_m = jam_m.min(gap_m);
    if min_gap(gap_m, v_e, v_l, b_l, 0.0) >= jam_m {
        return 0.0;
    }
    if gap_m <= jam_m && v_e > v_l {
        return f64::INFINITY;
    }
    // The least gap grows with the ego's deceleration: bisection up to one that stops the
    // ego within the room it has.
    let (mut lo, mut hi) = (0.0, 1.0);
    while min_gap(gap_m, v_e, v_l, b_l, hi) < jam_m {
        hi *= 2.0;
        if hi > 1e6 {
            return f64::INFINITY;
        }
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if min_gap(gap_m, v_e, v_l, b_l, mid) >= jam_m {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The least gap over time: the ego braking at `d`, the leader at `b_l` (both >= 0) until
/// each stops. It is reached where the speeds meet while both move, or once both stand.
fn min_gap(gap: f64, v_e: f64, v_l: f64, b_l: f64, d: f64) -> f64 {
    let closing = v_e - v_l;
    let t_leader = if b_l > 0.0 { v_l / b_l } else { f64::INFINITY };
    let t_ego = if d > 0.0 { v_e / d } else { f64::INFINITY };
    let mut least = gap;
    // Speeds meet while both move: the closing speed falls at d - b_l.
    if closing > 0.0 && d > b_l {
        let t_meet = closing / (d - b_l);
        if t_meet <= t_leader.min(t_ego) {
            least = least.min(gap - closing * closing / (2.0 * (d - b_l)));
        }
    }
    if t_leader.is_finite() {
        // The leader stands; the ego stops (or never does) behind it.
        let s_leader = v_l * v_l / (2.0 * b_l);
        let s_ego = if d > 0.0 { v_e * v_e / (2.0 * d) } else { f64::INFINITY };
        if t_ego >= t_leader {
            least = least.min(gap + s_leader - s_ego);
        }
    } else if closing > 0.0 && d <= b_l {
        // A leader holding its speed that the ego never matches.
        least = f64::NEG_INFINITY;
    }
    least
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The least gap by stepping both vehicles (1 ms): the closed form's oracle.
    fn simulated_min_gap(gap: f64, v_e: f64, v_l: f64, b_l: f64, d: f64) -> f64 {
        let (mut g, mut ve, mut vl, dt) = (gap, v_e, v_l, 1e-3);
        let mut least = g;
        for _ in 0..200_000 {
            let (ne, nl) = ((ve - d * dt).max(0.0), (vl - b_l * dt).max(0.0));
            g += 0.5 * (nl + vl) * dt - 0.5 * (ne + ve) * dt;
            (ve, vl) = (ne, nl);
            least = least.min(g);
            if ve == 0.0 && (vl == 0.0 || b_l == 0.0) {
                break;
            }
        }
        least
    }

    #[test]
    fn closed_form_matches_stepping() {
        for &(gap, v_e, v_l, b_l) in &[
            (55.0, 30.8, 26.4, 6.0),
            (40.0, 30.0, 30.0, 8.0),
            (38.0, 36.7, 28.0, 0.0),
            (20.0, 10.0, 0.0, 0.0),
            (10.0, 20.0, 25.0, 3.0),
        ] {
            for d in [1.0, 2.0, 4.0, 6.0, 9.0] {
                let closed = min_gap(gap, v_e, v_l, b_l, d).max(-1e3);
                let stepped = simulated_min_gap(gap, v_e, v_l, b_l, d);
                // A leader holding speed the ego never matches: the stepped gap runs away.
                if closed == -1e3 {
                    assert!(stepped < gap - 50.0, "{gap} {v_e} {v_l} {b_l} {d}: {stepped}");
                } else {
                    assert!(
                        (closed - stepped).abs() < 0.05,
                        "{gap} {v_e} {v_l} {b_l} {d}: {closed} vs {stepped}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_needed_deceleration_keeps_the_jam_distance_exactly() {
        for &(gap, v_e, v_l, a_l) in &[
            (55.0, 30.8, 26.4, -6.0),
            (40.0, 30.0, 30.0, -8.0),
            (38.0, 36.7, 28.0, 0.0),
            (20.0, 10.0, 0.0, 0.0),
        ] {
            let d = stopping_decel(gap, 2.0, v_e, v_l, a_l);
            let b_l = (-a_l).max(0.0);
            assert!(
                (simulated_min_gap(gap, v_e, v_l, b_l, d) - 2.0).abs() < 0.05,
                "{gap} {v_e} {v_l} {a_l}: {d}"
            );
            assert!(
                simulated_min_gap(gap, v_e, v_l, b_l, 0.9 * d) < 2.0 - 0.05,
                "{gap} {v_e} {v_l} {a_l}: less would do"
            );
        }
    }

    #[test]
    fn nothing_is_needed_behind_a_faster_or_distant_leader_and_closing_inside_the_jam_distance_is_infinite() {
        assert_eq!(stopping_decel(30.0, 2.0, 25.0, 30.0, 0.0), 0.0);
        assert_eq!(stopping_decel(1.0, 2.0, 25.0, 20.0, 0.0), f64::INFINITY);
        // Inside the jam distance and moving away: nothing to brake for.
        assert_eq!(stopping_decel(1.0, 2.0, 20.0, 25.0, 0.0), 0.0);
        // A leader braking to a stop always asks for some braking of a moving ego.
        assert!(stopping_decel(200.0, 2.0, 25.0, 25.0, -1.0) > 0.0);
    }
}
