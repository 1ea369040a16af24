use serde::{Deserialize, Serialize};

/// MOBIL lane-change parameters (Kesting, Treiber, Helbing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MobilParams {
    /// Politeness factor p.
    pub politeness: f64,
    /// Incentive threshold a_th (m/s^2).
    pub threshold: f64,
    /// Maximum safe deceleration b_safe (m/s^2, positive) imposed on the new follower.
    pub b_safe: f64,
}

impl Default for MobilParams {
    fn default() -> Self {
        MobilParams {
            politeness: 0.2,
            threshold: 0.1,
            b_safe: 4.0,
        }
    }
}

/// Accelerations and gaps MOBIL needs for one candidate lane change of vehicle `c`.
///
/// A tilde (`_new`) value is the acceleration after the change. Absent neighbours
/// (no new follower `n`, no old follower `o`) contribute `0.0` before and after.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MobilInput {
    /// Changer's acceleration now (a_c).
    pub a_c: f64,
    /// Changer's acceleration in the target lane (a~_c).
    pub a_c_new: f64,
    /// New follower's acceleration now (a_n).
    pub a_n: f64,
    /// New follower's acceleration behind the changer (a~_n).
    pub a_n_new: f64,
    /// Old follower's acceleration now (a_o).
    pub a_o: f64,
    /// Old follower's acceleration once the changer has left (a~_o).
    pub a_o_new: f64,
    /// Bumper gap to the leader in the target lane, if any.
    pub gap_new_leader: Option<f64>,
    /// Bumper gap to the follower in the target lane, if any.
    pub gap_new_follower: Option<f64>,
}

/// Outcome of [`mobil_evaluate`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MobilDecision {
    /// (a~_c - a_c) + p[(a~_n - a_n) + (a~_o - a_o)].
    pub incentive: f64,
    /// Incentive exceeds the threshold.
    pub beneficial: bool,
    /// Nobody would have to brake harder than b_safe and no gap would be negative.
    pub safe: bool,
}

impl MobilDecision {
    /// Whether the lane change should be started.
    pub fn accepted(&self) -> bool {
        self.beneficial && self.safe
    }
}

/// Evaluates the MOBIL incentive and safety criteria.
///
/// Beyond the textbook criterion `a~_n >= -b_safe`, the changer itself must not need to
/// brake harder than `b_safe` behind its new leader: that keeps forced (random) lane changes,
/// which skip the incentive test, from cutting in at a hopeless gap.
pub fn mobil_evaluate(input: &MobilInput, p: &MobilParams) -> MobilDecision {
    let incentive =
        (input.a_c_new - input.a_c) + p.politeness * ((input.a_n_new - input.a_n) + (input.a_o_new - input.a_o));
    let gaps_ok = [input.gap_new_leader, input.gap_new_follower]
        .into_iter()
        .flatten()
        .all(|g| g >= 0.0);
    let safe = gaps_ok && input.a_n_new >= -p.b_safe && input.a_c_new >= -p.b_safe;
    MobilDecision {
        incentive,
        beneficial: incentive > p.threshold,
        safe,
    }
}
