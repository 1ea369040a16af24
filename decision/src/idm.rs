//! IDM safety distance and the hysteresis thresholds built on it (paper III-C, III-D).

use crate::config::{Hysteresis, IdmParams, RearDistance};

/// IDM desired gap of a follower behind a leader, floored at the jam distance `d0` plus the
/// least time headway (`idm.min_time_headway_s`, 0: `d0` alone):
/// `d0 + v_f T + v_f (v_f - v_l) / (2 sqrt(a b))`.
pub fn idm_distance(p: &IdmParams, v_follower: f64, v_leader: f64) -> f64 {
    let dynamic = v_follower * (v_follower - v_leader) / (2.0 * (p.max_accel_mps2 * p.comfort_decel_mps2).sqrt());
    (p.jam_distance_m + v_follower * p.time_headway_s + dynamic).max(headway_floor(p, v_follower))
}

/// The least IDM distance of a follower at `v_follower`: `d0 + v_f * min_time_headway_s`.
fn headway_floor(p: &IdmParams, v_follower: f64) -> f64 {
    p.jam_distance_m + v_follower.max(0.0) * p.min_time_headway_s
}

/// Whether the ego takes the follower's place in the IDM distance to an SV: always for an
/// SV ahead; for one behind only with [`RearDistance::EgoSpeed`].
pub fn ego_as_follower(p: &IdmParams, sv_ahead: bool) -> bool {
    sv_ahead || p.rear_distance == RearDistance::EgoSpeed
}

/// The IDM distance between the ego (speed `v_ego`) and an SV (speed `v_sv`) ahead of it
/// or behind it ([`ego_as_follower`]).
pub fn sv_idm_distance(p: &IdmParams, v_ego: f64, v_sv: f64, sv_ahead: bool) -> f64 {
    if ego_as_follower(p, sv_ahead) {
        idm_distance(p, v_ego, v_sv)
    } else {
        idm_distance(p, v_sv, v_ego)
    }
}

/// Deterministic form of the chance constraint's right-hand side:
/// `d_hc = d_idm + z_eps sqrt(Sigma_Delta)`.
pub fn hard_margin(d_idm: f64, z_eps: f64, sigma_delta: f64) -> f64 {
    d_idm + z_eps * sigma_delta.sqrt()
}

/// Hard margins linearised in the ego's speed, for `idm.speed_dependent`: per branch and step
/// the unfloored IDM distance at the ego's current speed `v0` (and the branch's speed) plus the
/// quantile term `sigmas[h]`, and the common slope `d margin / d v_ego` (the floor at `d0` is a
/// row of its own). As follower: `T + (2 v0 - v_sv) / (2 sqrt(a b))`, never negative (slowing
/// down never widens the margin); as leader the distance is linear in the ego's speed with
/// slope `-v_sv / (2 sqrt(a b))`. With `idm.min_time_headway_s`, a distance below the
/// follower's headway floor is the floor, and where the SV's distance at its current speed is
/// floored the slope is the floor's (`min_time_headway_s` as follower, 0 as leader).
pub fn linearised_margins(
    p: &IdmParams,
    ego_follows: bool,
    v0: f64,
    v_sv: f64,
    branch_speeds: &[Vec<f64>],
    sigmas: &[f64],
) -> (Vec<Vec<f64>>, f64) {
    let root = 2.0 * (p.max_accel_mps2 * p.comfort_decel_mps2).sqrt();
    // The unfloored IDM distance, and whether the headway floor replaces it (the floor at d0
    // alone is a row of its own, so with no least headway nothing is floored here).
    let idm = |vf: f64, vl: f64| p.jam_distance_m + vf * p.time_headway_s + vf * (vf - vl) / root;
    let floored = |vf: f64, vl: f64| p.min_time_headway_s > 0.0 && idm(vf, vl) < headway_floor(p, vf);
    let margins = branch_speeds
        .iter()
        .map(|speeds| {
            sigmas
                .iter()
                .zip(speeds)
                .map(|(&s, &vb)| {
                    let (vf, vl) = if ego_follows { (v0, vb) } else { (vb, v0) };
                    let distance = if floored(vf, vl) {
                        headway_floor(p, vf)
                    } else {
                        idm(vf, vl)
                    };
                    distance + s
                })
                .collect()
        })
        .collect();
    let floored_now = if ego_follows {
        floored(v0, v_sv)
    } else {
        floored(v_sv, v0)
    };
    let slope = match (ego_follows, floored_now) {
        (true, true) => p.min_time_headway_s,
        (true, false) => (p.time_headway_s + (2.0 * v0 - v_sv) / root).max(0.0),
        (false, true) => 0.0,
        (false, false) => -v_sv / root,
    };
    (margins, slope)
}

/// Trigger and release distances of the hysteresis for one SV at one decision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// `eps_trig = clamp(k_eps d_idm, eps_min, eps_max)`.
    pub band: f64,
    pub trigger: f64,
    pub release: f64,
}

/// `d_trig = d_hc + gamma1 eps_trig`, `d_rel = d_hc + gamma2 eps_trig`.
pub fn thresholds(h: &Hysteresis, d_idm: f64, d_hc: f64) -> Thresholds {
    let band = (h.k_eps * d_idm).clamp(h.eps_min_m, h.eps_max_m);
    Thresholds {
        band,
        trigger: d_hc + h.gamma1 * band,
        release: d_hc + h.gamma2 * band,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The IDM distance alone, without the least time headway, with `T = 1.5` s and
    /// `a = 1.5`, `b = 2` (so `2 sqrt(a b) = 2 sqrt(3)`).
    fn idm_alone() -> IdmParams {
        IdmParams {
            min_time_headway_s: 0.0,
            time_headway_s: 1.5,
            max_accel_mps2: 1.5,
            comfort_decel_mps2: 2.0,
            ..IdmParams::default()
        }
    }

    #[test]
    fn idm_distance_by_hand() {
        let p = idm_alone();
        // 2 + 20*1.5 + 20*(20-15)/(2*sqrt(3)) = 32 + 100/3.4641016 = 60.867513
        assert!((idm_distance(&p, 20.0, 15.0) - 60.867_513_459).abs() < 1e-6);
        // Equal speeds: 2 + 30*1.5 = 47.
        assert!((idm_distance(&p, 30.0, 30.0) - 47.0).abs() < 1e-12);
        // A much faster leader drives the formula below d0: floored.
        assert_eq!(idm_distance(&p, 5.0, 40.0), 2.0);
        // Standing still: d0.
        assert_eq!(idm_distance(&p, 0.0, 10.0), 2.0);
    }

    #[test]
    fn the_headway_floor_holds_behind_a_faster_leader() {
        let p = IdmParams {
            min_time_headway_s: 0.6,
            ..idm_alone()
        };
        // Behind a leader 7 m/s faster IDM alone asks for d0: the floor asks for 0.6 s.
        assert_eq!(idm_distance(&idm_alone(), 26.0, 33.0), 2.0);
        assert!((idm_distance(&p, 26.0, 33.0) - (2.0 + 26.0 * 0.6)).abs() < 1e-12);
        // Where IDM asks for more, the floor changes nothing.
        assert_eq!(idm_distance(&p, 30.0, 30.0), idm_distance(&idm_alone(), 30.0, 30.0));
        // Linearised: the floored branch is the floor (plus its quantile term), the slope the
        // floor's; an SV behind that is floored no longer depends on the ego's speed.
        let (m, slope) = linearised_margins(&p, true, 26.0, 33.0, &[vec![33.0], vec![20.0]], &[1.0]);
        assert!((m[0][0] - (2.0 + 26.0 * 0.6 + 1.0)).abs() < 1e-12);
        assert!(m[1][0] > 2.0 + 26.0 * 1.5);
        assert_eq!(slope, 0.6);
        let (m, slope) = linearised_margins(&p, false, 33.0, 26.0, &[vec![26.0]], &[0.0]);
        assert!((m[0][0] - (2.0 + 26.0 * 0.6)).abs() < 1e-12);
        assert_eq!(slope, 0.0);
    }

    #[test]
    fn linearised_margins_by_hand() {
        let p = idm_alone();
        let root = 2.0 * 3.0f64.sqrt();
        // Ego at 20 following an SV at 15 (branch speed 14 at the step): unfloored IDM
        // 2 + 30 + 20 * 6 / root; slope 1.5 + 25 / root.
        let (m, slope) = linearised_margins(&p, true, 20.0, 15.0, &[vec![14.0]], &[1.0]);
        assert!((m[0][0] - (33.0 + 120.0 / root)).abs() < 1e-9);
        assert!((slope - (1.5 + 25.0 / root)).abs() < 1e-12);
        // The tangent is exact at v0 and below the convex IDM distance elsewhere.
        let exact = |v: f64| 2.0 + 1.5 * v + v * (v - 14.0) / root + 1.0;
        assert!((m[0][0] - exact(20.0)).abs() < 1e-9);
        assert!(m[0][0] + slope * (18.0 - 20.0) <= exact(18.0) + (15.0 - 14.0) * 2.0 / root + 1e-9);
        // SV at 25 following the ego at 20: linear in the ego speed, slope -25 / root.
        let (m, slope) = linearised_margins(&p, false, 20.0, 25.0, &[vec![25.0]], &[0.0]);
        assert!((m[0][0] - (2.0 + 37.5 + 125.0 / root)).abs() < 1e-9);
        assert!((slope + 25.0 / root).abs() < 1e-12);
        // A slow ego behind a fast SV: the follower slope is clamped at zero.
        let (_, slope) = linearised_margins(&p, true, 5.0, 40.0, &[vec![40.0]], &[0.0]);
        assert_eq!(slope, 0.0);
    }

    #[test]
    fn hard_margin_adds_the_quantile() {
        assert!((hard_margin(40.0, 1.645, 0.25) - 40.8225).abs() < 1e-12);
    }

    #[test]
    fn thresholds_clamp_the_band() {
        let h = Hysteresis::default();
        // k_eps * d_idm = 0.5 * 8 = 4 < eps_min = 6.
        let t = thresholds(&h, 8.0, 9.0);
        assert_eq!(t.band, 6.0);
        assert!((t.trigger - 15.0).abs() < 1e-12);
        assert!((t.release - 17.4).abs() < 1e-12);
        // 0.5 * 30 = 15 inside the bounds.
        let t = thresholds(&h, 30.0, 31.0);
        assert_eq!(t.band, 15.0);
        assert!((t.release - t.trigger - 6.0).abs() < 1e-12);
        // 0.5 * 60 = 30 > eps_max = 22.
        assert_eq!(thresholds(&h, 60.0, 61.0).band, 22.0);
    }
}
