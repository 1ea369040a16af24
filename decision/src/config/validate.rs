//! What a configuration must hold for the problem to mean anything: checked when a file is
//! parsed and when a planner is built.

use super::PlannerConfig;
use crate::error::ConfigError;

impl PlannerConfig {
    /// Reject settings that make the problem meaningless.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field: &'static str, why: &'static str| Err(ConfigError::Invalid { field, why });
        let t = &self.timing;
        if !(t.step_s.is_finite() && t.step_s > 0.0) {
            return bad("timing.step_s", "must be positive");
        }
        if !(1..=6).contains(&t.horizon) {
            return bad("timing.horizon", "must be in 1..=6");
        }
        let e = &self.ego;
        if !(e.decel_mps2 < 0.0 && e.accel_mps2 > 0.0) {
            return bad("ego", "decel must be negative and accel positive");
        }
        let p = &self.prediction;
        for (field, value) in [
            ("prediction.p_keep_long", p.p_keep_long),
            ("prediction.p_keep_lat", p.p_keep_lat),
            ("prediction.p_min", p.p_min),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(ConfigError::Invalid {
                    field,
                    why: "must be a probability",
                });
            }
        }
        if !(p.epsilon > 0.0 && p.epsilon < 0.5) {
            return bad("prediction.epsilon", "must be in (0, 0.5)");
        }
        if p.max_branches == 0 {
            return bad("prediction.max_branches", "must be at least 1");
        }
        if !(0.0..=1.0).contains(&p.p_min_relative) {
            return bad("prediction.p_min_relative", "must be in [0, 1]");
        }
        if let Some((field, why)) = p.evidence.invalid() {
            return bad(field, why);
        }
        if p.noise_diag.iter().any(|q| !(q.is_finite() && *q >= 0.0)) {
            return bad("prediction.noise_diag", "must be finite and non-negative");
        }
        if !(p.braking_end_margin_mps.is_finite() && p.braking_end_margin_mps >= 0.0) {
            return bad("prediction.braking_end_margin_mps", "must be finite and non-negative");
        }
        let h = &self.hysteresis;
        if h.gamma1.partial_cmp(&h.gamma2) != Some(std::cmp::Ordering::Less) {
            return bad("hysteresis", "gamma1 must be below gamma2");
        }
        if !matches!(
            h.eps_min_m.partial_cmp(&h.eps_max_m),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        ) {
            return bad("hysteresis", "eps_min_m must not exceed eps_max_m");
        }
        if !(h.anticipation_s.is_finite() && h.anticipation_s >= 0.0) {
            return bad("hysteresis.anticipation_s", "must be finite and non-negative");
        }
        let c = &self.cost;
        if !(c.w_global > c.w_slack && c.w_slack >= 0.0) {
            return bad("cost.w_global", "must exceed cost.w_slack (w_q >> w_s)");
        }
        if c.w_beta
            .iter()
            .chain(&c.w_beta_terminal)
            .chain([
                &c.w_lane_change,
                &c.w_speed,
                &c.w_brake,
                &c.w_switch,
                &c.w_speed_terminal,
                &c.w_hard_brake,
                &c.w_firm_brake,
                &c.w_peak_brake,
                &c.w_lane_speed,
                &c.lane_lookahead_m,
                &c.lane_horizon_s,
            ])
            .any(|w| !(w.is_finite() && *w >= 0.0))
        {
            return bad("cost", "weights must be finite and non-negative");
        }
        if !(self.recovery.gamma > 0.0 && self.recovery.gamma < 1.0) {
            return bad("recovery.gamma", "must be in (0, 1)");
        }
        if !(e.max_decel_mps2 <= e.comfort_decel_mps2
            && e.comfort_decel_mps2 <= e.firm_decel_mps2
            && e.firm_decel_mps2 <= -e.cruise_band_mps2
            && e.cruise_band_mps2 >= 0.0
            && e.cruise_band_mps2 <= e.accel_mps2)
        {
            return bad(
                "ego",
                "need max_decel <= comfort_decel <= firm_decel <= -cruise_band <= 0 <= cruise_band <= accel",
            );
        }
        let strongest_state_braking = if e.continuous_accel {
            e.max_decel_mps2
        } else {
            e.decel_mps2
        };
        if !(e.emergency_decel_mps2.is_finite() && e.emergency_decel_mps2 <= strongest_state_braking) {
            return bad(
                "ego.emergency_decel_mps2",
                "must be finite and at most the strongest braking of beta = -1 (max_decel with continuous_accel, decel without)",
            );
        }
        // Behind an SV at the ego's speed the room asks for up to itself: beyond the planned
        // range, close following would be an emergency that skips the MPC.
        if !(e.lead_brake_room_mps2.is_finite()
            && e.lead_brake_room_mps2 >= 0.0
            && e.lead_brake_room_mps2 <= -strongest_state_braking)
        {
            return bad(
                "ego.lead_brake_room_mps2",
                "must be finite, non-negative and at most the strongest braking of beta = -1",
            );
        }
        // Checked only where it is priced: a configuration without the peak price keeps
        // whatever comfort level it had.
        let priced = c.w_peak_brake > 0.0;
        if !(e.peak_decel_mps2.is_finite()
            && (!priced || (e.max_decel_mps2 <= e.peak_decel_mps2 && e.peak_decel_mps2 <= e.comfort_decel_mps2)))
        {
            return bad(
                "ego.peak_decel_mps2",
                "must be finite, and with cost.w_peak_brake on within [max_decel, comfort_decel]",
            );
        }
        let idm = &self.idm;
        // The dynamic term divides by sqrt(a b): zero or a negative would make every margin
        // infinite or NaN.
        for (field, value) in [
            ("idm.max_accel_mps2", idm.max_accel_mps2),
            ("idm.comfort_decel_mps2", idm.comfort_decel_mps2),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, "must be positive (a magnitude)");
            }
        }
        if !(idm.jam_distance_m.is_finite() && idm.jam_distance_m >= 0.0) {
            return bad("idm.jam_distance_m", "must be finite and non-negative");
        }
        if !(0.0..1.0).contains(&self.idm.violation_decay) {
            return bad("idm.violation_decay", "must be in [0, 1)");
        }
        if !(self.idm.violation_recovery_mps2.is_finite() && self.idm.violation_recovery_mps2 >= 0.0) {
            return bad("idm.violation_recovery_mps2", "must be finite and non-negative");
        }
        if !(self.idm.min_time_headway_s >= 0.0 && self.idm.min_time_headway_s <= self.idm.time_headway_s) {
            return bad("idm.min_time_headway_s", "must be in [0, time_headway_s]");
        }
        if !(e.lane_change_s.is_finite() && e.lane_change_s > 0.0) {
            return bad("ego.lane_change_s", "must be positive");
        }
        if self.perception.max_svs == 0 || self.perception.max_svs > crate::MAX_INPUT_SVS {
            return bad("perception.max_svs", "must be in 1..=MAX_INPUT_SVS");
        }
        if self.perception.max_lanes == 0 || self.perception.max_lanes > 16 {
            return bad("perception.max_lanes", "must be in 1..=16");
        }
        if !(self.solver.time_limit_s.is_finite() && self.solver.time_limit_s > 0.0) {
            return bad("solver.time_limit_s", "must be positive");
        }
        Ok(())
    }
}
