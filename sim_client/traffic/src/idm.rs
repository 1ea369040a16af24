use serde::{Deserialize, Serialize};

/// Intelligent Driver Model parameters (Treiber et al.).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IdmParams {
    /// Minimum standstill gap d0 (m).
    pub min_gap: f64,
    /// Desired time headway T (s).
    pub time_headway: f64,
    /// Maximum acceleration a_max (m/s^2).
    pub a_max: f64,
    /// Comfortable deceleration b (m/s^2, positive).
    pub b_comfort: f64,
    /// Free-road exponent delta.
    pub delta: f64,
    /// Physical braking limit (m/s^2, negative); IDM output is clamped to it.
    pub a_min: f64,
}

impl Default for IdmParams {
    fn default() -> Self {
        IdmParams {
            min_gap: 2.0,
            time_headway: 1.5,
            a_max: 1.5,
            b_comfort: 2.0,
            delta: 4.0,
            a_min: -9.0,
        }
    }
}

/// IDM acceleration of a follower at speed `v` with desired speed `v_desired`.
///
/// `gap` is bumper to bumper to the leader (use `f64::INFINITY` for a free road) and
/// `dv_closing = v - v_leader` (positive when approaching). The result is clamped to
/// `[a_min, a_max]`; an overlapping leader (`gap <= 0`) yields full braking.
pub fn idm_acceleration(v: f64, v_desired: f64, gap: f64, dv_closing: f64, p: &IdmParams) -> f64 {
    let free = 1.0 - (v / v_desired).powf(p.delta);
    let interaction = if gap.is_infinite() {
        0.0
    } else if gap <= 0.0 {
        return p.a_min;
    } else {
        let dynamic = v * p.time_headway + v * dv_closing / (2.0 * (p.a_max * p.b_comfort).sqrt());
        let s_star = p.min_gap + dynamic.max(0.0);
        (s_star / gap).powi(2)
    };
    (p.a_max * (free - interaction)).clamp(p.a_min, p.a_max)
}
