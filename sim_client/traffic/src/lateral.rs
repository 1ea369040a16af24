use serde::{Deserialize, Serialize};

/// Quintic smoothstep `10s^3 - 15s^4 + 6s^5` on `[0, 1]`: zero lateral speed and
/// acceleration at both ends, symmetric about `s = 0.5` (value 0.5 there).
pub fn smooth_profile(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * s * (10.0 + s * (-15.0 + 6.0 * s))
}

/// A lateral manoeuvre under way: smooth motion from `from_y` to `to_y`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LaneChange {
    /// Lane the vehicle was in (nearest centre) when the manoeuvre started.
    pub origin_lane: u8,
    /// Lane being driven to.
    pub target_lane: u8,
    /// Lateral position at the start.
    pub from_y: f64,
    /// Centre of the target lane.
    pub to_y: f64,
    /// Total duration (s).
    pub duration: f64,
    /// Low-level steps elapsed; counted in steps so completion does not drift with
    /// floating-point accumulation of `dt`.
    pub steps_elapsed: u32,
}

impl LaneChange {
    /// Fraction completed in `[0, 1]` given the step length.
    pub fn progress(&self, dt: f64) -> f64 {
        (f64::from(self.steps_elapsed) * dt / self.duration).clamp(0.0, 1.0)
    }

    /// Whether the manoeuvre has finished (with a tolerance for rounding of `dt`).
    pub fn is_complete(&self, dt: f64) -> bool {
        f64::from(self.steps_elapsed) * dt >= self.duration - 1e-9
    }

    /// Lateral position at the current progress.
    pub fn y(&self, dt: f64) -> f64 {
        if self.is_complete(dt) {
            self.to_y
        } else {
            self.from_y + (self.to_y - self.from_y) * smooth_profile(self.progress(dt))
        }
    }
}
