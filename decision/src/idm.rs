//! IDM safety distance and the hysteresis thresholds built on it (paper III-C, III-D).

use crate::config::{Hysteresis, IdmParams};

/// IDM desired gap of a follower behind a leader, floored at the jam distance `d0`:
/// `d0 + v_f T + v_f (v_f - v_l) / (2 sqrt(a b))`.
pub fn idm_distance(p: &IdmParams, v_follower: f64, v_leader: f64) -> f64 {
    let dynamic = v_follower * (v_follower - v_leader) / (2.0 * (p.max_accel_mps2 * p.comfort_decel_mps2).sqrt());
    (p.jam_distance_m + v_follower * p.time_headway_s + dynamic).max(p.jam_distance_m)
}

/// Deterministic form of the chance constraint's right-hand side:
/// `d_hc = d_idm + z_eps sqrt(Sigma_Delta)`.
pub fn hard_margin(d_idm: f64, z_eps: f64, sigma_delta: f64) -> f64 {
    d_idm + z_eps * sigma_delta.sqrt()
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

    #[test]
    fn idm_distance_by_hand() {
        let p = IdmParams::default();
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
