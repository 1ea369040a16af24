//! The braking that keeps the ego behind a braking leader: the least deceleration with which
//! the gap never falls below the jam distance, the leader braking on at its measured
//! deceleration until it reaches the speed its braking ends at (`braking_end.rs`: the speed
//! of the slower vehicle it brakes for, or a standstill when nothing visible explains it), or
//! holding its speed when it does not brake.
//!
//! The IDM margin is a gap to settle at, not a limit: the violation allowance lets the ego
//! recover it comfortably. That must never mean braking less than this, or a leader braking
//! hard is followed at a comfortable deceleration into its bumper.

/// Least constant deceleration (m/s^2, >= 0) of an ego at `v_ego` keeping at least `jam_m`
/// behind a leader `gap_m` ahead at `v_leader` accelerating at `a_leader` (a negative value
/// brakes it down to `v_end`, 0 for a stop; otherwise it holds its speed). A leader already
/// closer than `jam_m` (a cut-in at the bumper) is to come no closer than it is. Infinite
/// when no braking does that (closer than `jam_m` and closing).
pub fn stopping_decel(gap_m: f64, jam_m: f64, v_ego: f64, v_leader: f64, a_leader: f64, v_end: f64) -> f64 {
    let leader = Profile::braking_to(v_leader, -a_leader, v_end);
    least_decel(gap_m, jam_m, leader, |d| Profile::braking_to(v_ego, d, 0.0))
}

/// Least deceleration (m/s^2, >= 0) the ego may hold for `hold_s` before braking at
/// `escalation_mps2` (or on at its own, if harder) keeps it `jam_m` behind a leader braking
/// at its measured deceleration to a standstill: braking that trusts a leader to stop
/// braking at some speed, and can still answer it when it does not, in time.
pub fn escalating_decel(
    gap_m: f64,
    jam_m: f64,
    v_ego: f64,
    v_leader: f64,
    a_leader: f64,
    hold_s: f64,
    escalation_mps2: f64,
) -> f64 {
    let leader = Profile::braking_to(v_leader, -a_leader, 0.0);
    least_decel(gap_m, jam_m, leader, |d| {
        Profile::two_phase(v_ego, d, hold_s, d.max(escalation_mps2))
    })
}

/// The least `d` whose ego profile `ego(d)` keeps the gap at `jam_m` or more: bisection, as
/// the least gap grows with the ego's braking.
fn least_decel(gap_m: f64, jam_m: f64, leader: Profile, ego: impl Fn(f64) -> Profile) -> f64 {
    let jam_m = jam_m.min(gap_m);
    if min_gap(gap_m, &ego(0.0), &leader) >= jam_m {
        return 0.0;
    }
    if gap_m <= jam_m && ego(0.0).v0 > leader.v0 {
        return f64::INFINITY;
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    while min_gap(gap_m, &ego(hi), &leader) < jam_m {
        hi *= 2.0;
        if hi > 1e6 {
            return f64::INFINITY;
        }
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if min_gap(gap_m, &ego(mid), &leader) >= jam_m {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// A speed profile: from `v0`, up to two phases `(duration, acceleration)` in turn, then the
/// speed reached held (a standstill at 0).
#[derive(Debug, Clone, Copy)]
struct Profile {
    v0: f64,
    phases: [(f64, f64); 2],
    /// The speed held after the phases (exact: summing the phases may leave a rounding
    /// residue that would read as never stopping).
    v_final: f64,
}

impl Profile {
    /// Braking at `b` (>= 0; otherwise holding `v`) down to `v_end`, then holding it.
    fn braking_to(v: f64, b: f64, v_end: f64) -> Profile {
        let v = v.max(0.0);
        let (b, v_end) = (b.max(0.0), v_end.clamp(0.0, v));
        let (first, v_final) = if b > 0.0 {
            (((v - v_end) / b, -b), v_end)
        } else {
            ((0.0, 0.0), v)
        };
        Profile {
            v0: v,
            phases: [first, (0.0, 0.0)],
            v_final,
        }
    }

    /// Braking at `d1` for `hold_s` (or to a standstill), then at `d2` to a standstill.
    fn two_phase(v: f64, d1: f64, hold_s: f64, d2: f64) -> Profile {
        let v = v.max(0.0);
        let t1 = if d1 > 0.0 { hold_s.min(v / d1) } else { hold_s };
        let v1 = v - d1 * t1;
        let (second, v_final) = if d2 > 0.0 {
            ((v1 / d2, -d2), 0.0)
        } else {
            ((0.0, 0.0), v1)
        };
        Profile {
            v0: v,
            phases: [(t1, -d1), second],
            v_final,
        }
    }

    /// Speed, distance covered and acceleration at `t`.
    fn at(&self, t: f64) -> (f64, f64, f64) {
        let (mut v, mut x, mut left) = (self.v0, 0.0, t);
        for &(duration, a) in &self.phases {
            if left < duration {
                return (v + a * left, x + v * left + 0.5 * a * left * left, a);
            }
            x += v * duration + 0.5 * a * duration * duration;
            v += a * duration;
            left -= duration;
        }
        (self.v_final, x + self.v_final * left, 0.0)
    }

    /// When its phases end.
    fn breakpoints(&self) -> [f64; 2] {
        let t1 = self.phases[0].0;
        [t1, t1 + self.phases[1].0]
    }
}

/// The least gap over time between an ego and a leader `gap` ahead, each on its profile.
/// The gap's rate (the leader's speed less the ego's) is continuous and piecewise linear, so
/// the least gap lies at the start, at a breakpoint, where the rate crosses zero within a
/// piece, or (falling without end) at infinity.
fn min_gap(gap: f64, ego: &Profile, leader: &Profile) -> f64 {
    if leader.v_final < ego.v_final {
        return f64::NEG_INFINITY;
    }
    let gap_at = |t: f64| gap + leader.at(t).1 - ego.at(t).1;
    // The start and the four breakpoints, without allocating: the bisection calls this some
    // 60 times per SV.
    let [e1, e2] = ego.breakpoints();
    let [l1, l2] = leader.breakpoints();
    let mut times = [0.0, e1, e2, l1, l2];
    times.sort_by(f64::total_cmp);
    let mut least = gap;
    for pair in times.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if !b.is_finite() {
            break;
        }
        least = least.min(gap_at(b));
        if b <= a {
            continue;
        }
        let mid = 0.5 * (a + b);
        let (rate, slope) = (leader.at(a).0 - ego.at(a).0, leader.at(mid).2 - ego.at(mid).2);
        if slope != 0.0 {
            let t = a - rate / slope;
            if t > a && t < b {
                least = least.min(gap_at(t));
            }
        }
    }
    least
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The least gap by stepping both vehicles (1 ms): the closed form's oracle.
    fn simulated_min_gap(gap: f64, v_e: f64, v_l: f64, b_l: f64, v_end: f64, d: f64) -> f64 {
        let (mut g, mut ve, mut vl, dt) = (gap, v_e, v_l, 1e-3);
        let floor = if b_l > 0.0 { v_end } else { v_l };
        let mut least = g;
        for _ in 0..200_000 {
            let (ne, nl) = ((ve - d * dt).max(0.0), (vl - b_l * dt).max(floor));
            g += 0.5 * (nl + vl) * dt - 0.5 * (ne + ve) * dt;
            (ve, vl) = (ne, nl);
            least = least.min(g);
            if ve == 0.0 && (vl == floor || b_l == 0.0) {
                break;
            }
        }
        least
    }

    fn closed_min_gap(gap: f64, v_e: f64, v_l: f64, b_l: f64, v_end: f64, d: f64) -> f64 {
        min_gap(
            gap,
            &Profile::braking_to(v_e, d, 0.0),
            &Profile::braking_to(v_l, b_l, v_end),
        )
    }

    #[test]
    fn closed_form_matches_stepping() {
        for &(gap, v_e, v_l, b_l, v_end) in &[
            (55.0, 30.8, 26.4, 6.0, 0.0),
            (40.0, 30.0, 30.0, 8.0, 0.0),
            (38.0, 36.7, 28.0, 0.0, 0.0),
            (20.0, 10.0, 0.0, 0.0, 0.0),
            (10.0, 20.0, 25.0, 3.0, 0.0),
            // Braking that ends at a speed: below, at and above the ego's.
            (40.0, 30.0, 30.0, 9.0, 20.0),
            (25.0, 22.0, 30.0, 6.0, 22.0),
            (15.0, 18.0, 26.0, 4.0, 24.0),
            (60.0, 35.0, 28.0, 2.0, 12.0),
        ] {
            for d in [0.0, 1.0, 2.0, 4.0, 6.0, 9.0] {
                let closed = closed_min_gap(gap, v_e, v_l, b_l, v_end, d).max(-1e3);
                let stepped = simulated_min_gap(gap, v_e, v_l, b_l, v_end, d);
                // A leader the ego never matches: the stepped gap runs away.
                if closed == -1e3 {
                    assert!(stepped < gap - 50.0, "{gap} {v_e} {v_l} {b_l} {d}: {stepped}");
                } else {
                    assert!(
                        (closed - stepped).abs() < 0.05,
                        "{gap} {v_e} {v_l} {b_l} {v_end} {d}: {closed} vs {stepped}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_needed_deceleration_keeps_the_jam_distance_exactly() {
        for &(gap, v_e, v_l, a_l, v_end) in &[
            (55.0, 30.8, 26.4, -6.0, 0.0),
            (40.0, 30.0, 30.0, -8.0, 0.0),
            (38.0, 36.7, 28.0, 0.0, 0.0),
            (20.0, 10.0, 0.0, 0.0, 0.0),
            (40.0, 30.0, 30.0, -9.0, 20.0),
            (30.0, 32.0, 28.0, -3.0, 15.0),
        ] {
            let d = stopping_decel(gap, 2.0, v_e, v_l, a_l, v_end);
            let b_l = (-a_l).max(0.0);
            assert!(
                (simulated_min_gap(gap, v_e, v_l, b_l, v_end, d) - 2.0).abs() < 0.05,
                "{gap} {v_e} {v_l} {a_l} {v_end}: {d}"
            );
            assert!(
                simulated_min_gap(gap, v_e, v_l, b_l, v_end, 0.9 * d) < 2.0 - 0.05,
                "{gap} {v_e} {v_l} {a_l} {v_end}: less would do"
            );
        }
    }

    #[test]
    fn nothing_is_needed_behind_a_faster_or_distant_leader_and_closing_inside_the_jam_distance_is_infinite() {
        assert_eq!(stopping_decel(30.0, 2.0, 25.0, 30.0, 0.0, 0.0), 0.0);
        assert_eq!(stopping_decel(1.0, 2.0, 25.0, 20.0, 0.0, 0.0), f64::INFINITY);
        // Inside the jam distance and moving away: nothing to brake for.
        assert_eq!(stopping_decel(1.0, 2.0, 20.0, 25.0, 0.0, 0.0), 0.0);
        // A leader braking to a stop always asks for some braking of a moving ego.
        assert!(stopping_decel(200.0, 2.0, 25.0, 25.0, -1.0, 0.0) > 0.0);
        // ... one braking down to a speed above the ego's asks for none.
        assert_eq!(stopping_decel(30.0, 2.0, 20.0, 25.0, -6.0, 21.0), 0.0);
    }

    #[test]
    fn a_braking_that_ends_above_a_standstill_asks_for_less() {
        // 40 m behind a leader at 30 m/s braking at 9 m/s^2: to a stop it takes about 5 m/s^2
        // (about 900 / (2 * 88)); ending at 20 m/s, a fraction of it.
        let to_stop = stopping_decel(40.0, 2.0, 30.0, 30.0, -9.0, 0.0);
        let to_twenty = stopping_decel(40.0, 2.0, 30.0, 30.0, -9.0, 20.0);
        assert!(to_stop > 4.5 && to_stop < 5.5, "{to_stop}");
        assert!(to_twenty < 0.5 * to_stop, "{to_twenty}");
    }

    #[test]
    fn escalating_later_needs_less_now_and_answers_a_stop_in_time() {
        // 60 m behind a leader at 30 m/s braking at 9 m/s^2: to a stop at one deceleration
        // about 4.2 m/s^2; holding the braking 1.5 s before 6 m/s^2 lets it start lower.
        let constant = stopping_decel(60.0, 2.0, 30.0, 30.0, -9.0, 0.0);
        let held = escalating_decel(60.0, 2.0, 30.0, 30.0, -9.0, 1.5, 6.0);
        assert!(constant > 4.0 && constant < 4.4, "{constant}");
        assert!(held > 1.0 && held < 2.0, "{held}");
        // The profile it stands for keeps the jam distance exactly (stepped at 1 ms).
        let (dt, (mut g, mut ve, mut vl)) = (1e-3, (60.0, 30.0f64, 30.0f64));
        let mut least = g;
        for k in 0..20_000 {
            let d = if f64::from(k) * dt < 1.5 { held } else { 6.0 };
            let (ne, nl) = ((ve - d * dt).max(0.0), (vl - 9.0 * dt).max(0.0));
            g += 0.5 * (nl + vl) * dt - 0.5 * (ne + ve) * dt;
            (ve, vl) = (ne, nl);
            least = least.min(g);
        }
        assert!((least - 2.0).abs() < 0.05, "{least}");
        // No hold: the constant answer (escalation below it changes nothing).
        assert!((escalating_decel(60.0, 2.0, 30.0, 30.0, -9.0, 0.0, 1.0) - constant).abs() < 1e-6);
    }
}
