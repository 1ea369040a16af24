//! `[prediction.evidence]`: what an SV's observed motion and surroundings say about its next
//! maneuver (docs/formulation-notes.md, "A scenario tree that lives").

use serde::{Deserialize, Serialize};

/// How the first step of an SV's scenario tree follows the evidence. Off, every step has the
/// background probabilities `p_keep_lat` / `p_keep_long` (the paper's and formulation.md's
/// tree).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Evidence {
    pub enabled: bool,
    /// Spread of the lateral velocity an SV keeping its lane shows (sensor noise and lane
    /// keeping), m/s: a Gaussian around 0.
    pub keep_lateral_sigma_mps: f64,
    /// An SV changing lanes moves sideways at up to this speed, m/s: its lateral velocity
    /// towards the new lane is uniform on `[0, this]`.
    pub change_lateral_speed_max_mps: f64,
    /// Prior probability of a lane change towards a side, per decision, for an SV held up by a
    /// slower vehicle ahead in its lane (MOBIL's incentive) while that side's lane is freer;
    /// without an incentive the prior is the background `(1 - p_keep_lat) / 2`.
    pub incentive_lane_change: f64,
    /// The incentive is full when the SV is this much faster than its leader, m/s (it grows
    /// from zero at 1 m/s).
    pub incentive_speed_gap_mps: f64,
    /// Only a leader within this distance holds an SV up, m.
    pub incentive_range_m: f64,
    /// An SV closing in on its own leader with a time to collision below this will brake
    /// (the probability grows linearly as the time falls to 0), s.
    pub brake_ttc_s: f64,
    /// Probability that an SV brakes in the next step at a time to collision of 0.
    pub brake_max: f64,
}

impl Default for Evidence {
    fn default() -> Self {
        Self {
            enabled: true,
            keep_lateral_sigma_mps: 0.05,
            change_lateral_speed_max_mps: 2.5,
            incentive_lane_change: 0.16,
            incentive_speed_gap_mps: 4.0,
            incentive_range_m: 80.0,
            brake_ttc_s: 6.0,
            brake_max: 0.8,
        }
    }
}

impl Evidence {
    /// The first invalid field, if any.
    pub(crate) fn invalid(&self) -> Option<(&'static str, &'static str)> {
        let positive = |x: f64| x.is_finite() && x > 0.0;
        let probability = |x: f64| (0.0..1.0).contains(&x);
        if !positive(self.keep_lateral_sigma_mps) {
            return Some(("prediction.evidence.keep_lateral_sigma_mps", "must be positive"));
        }
        if !positive(self.change_lateral_speed_max_mps) {
            return Some(("prediction.evidence.change_lateral_speed_max_mps", "must be positive"));
        }
        if !probability(self.incentive_lane_change) || self.incentive_lane_change > 0.45 {
            return Some(("prediction.evidence.incentive_lane_change", "must be in [0, 0.45]"));
        }
        if !(positive(self.incentive_speed_gap_mps) && positive(self.incentive_range_m) && positive(self.brake_ttc_s)) {
            return Some(("prediction.evidence", "speeds, ranges and times must be positive"));
        }
        if !probability(self.brake_max) {
            return Some(("prediction.evidence.brake_max", "must be in [0, 1)"));
        }
        None
    }
}
