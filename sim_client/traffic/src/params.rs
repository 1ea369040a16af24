use serde::{Deserialize, Serialize};

use crate::{IdmParams, MobilParams, SimError};

/// Random behaviour of surrounding vehicles (the HMDP maneuver switches).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SvBehaviour {
    /// Probability of keeping the longitudinal mode beta at each decision instant.
    pub p_keep_long: f64,
    /// Probability of attempting a random lane change at each decision instant.
    pub p_random_lane_change: f64,
    /// Deceleration (m/s^2, positive) applied in the gentle slowdown mode beta = -1.
    pub gentle_decel: f64,
}

impl Default for SvBehaviour {
    fn default() -> Self {
        SvBehaviour {
            p_keep_long: 0.8,
            p_random_lane_change: 0.01,
            gentle_decel: 1.0,
        }
    }
}

impl SvBehaviour {
    /// Rejects probabilities outside `[0, 1]` and a non-positive slowdown.
    pub fn validate(&self) -> Result<(), SimError> {
        probability("sv.p_keep_long", self.p_keep_long)?;
        probability("sv.p_random_lane_change", self.p_random_lane_change)?;
        positive("sv.gentle_decel", self.gentle_decel)
    }

    /// No random switches: SVs are pure IDM + MOBIL drivers (Case-1 style scenes).
    pub fn deterministic() -> Self {
        SvBehaviour {
            p_keep_long: 1.0,
            p_random_lane_change: 0.0,
            ..Self::default()
        }
    }
}

/// All tunable constants of the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimParams {
    /// Low-level step T_l (s).
    pub dt: f64,
    /// Interval between SV / rule-based decisions (s); must be a multiple of `dt`.
    pub decision_period: f64,
    /// Duration T_lc of a one-lane change (s).
    pub lane_change_duration: f64,
    /// Shortest commanded ego lateral manoeuvre (s).
    pub min_lane_change_duration: f64,
    /// Ego jerk bound (m/s^3), whatever drives the ego.
    pub jerk_max: f64,
    /// Ego target acceleration for beta = -1 (m/s^2, negative).
    pub a_dec: f64,
    /// Ego target acceleration for beta = +1 (m/s^2).
    pub a_acc: f64,
    /// Car-following model.
    pub idm: IdmParams,
    /// Lane-change model.
    pub mobil: MobilParams,
    /// Random SV behaviour.
    pub sv: SvBehaviour,
    /// Perception range, centre to centre, ahead or behind (m).
    pub sensor_range: f64,
}

impl Default for SimParams {
    fn default() -> Self {
        SimParams {
            dt: 0.1,
            decision_period: 0.4,
            lane_change_duration: 3.0,
            min_lane_change_duration: 0.5,
            jerk_max: 15.0,
            a_dec: -3.0,
            a_acc: 1.5,
            idm: IdmParams::default(),
            mobil: MobilParams::default(),
            sv: SvBehaviour::default(),
            sensor_range: 200.0,
        }
    }
}

fn positive(name: &'static str, v: f64) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SimError::InvalidParameter {
            name,
            reason: "must be finite and positive",
        })
    }
}

fn probability(name: &'static str, v: f64) -> Result<(), SimError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(SimError::InvalidParameter {
            name,
            reason: "must be a probability in [0, 1]",
        })
    }
}

impl SimParams {
    /// Low-level steps per decision period.
    pub fn steps_per_decision(&self) -> u64 {
        (self.decision_period / self.dt).round().max(1.0) as u64
    }

    /// Rejects parameters that would make the simulation meaningless.
    pub fn validate(&self) -> Result<(), SimError> {
        positive("dt", self.dt)?;
        positive("decision_period", self.decision_period)?;
        let ratio = self.decision_period / self.dt;
        if ratio < 0.5 || (ratio - ratio.round()).abs() > 1e-6 {
            return Err(SimError::InvalidParameter {
                name: "decision_period",
                reason: "must be a whole multiple of dt",
            });
        }
        positive("lane_change_duration", self.lane_change_duration)?;
        positive("min_lane_change_duration", self.min_lane_change_duration)?;
        positive("jerk_max", self.jerk_max)?;
        positive("a_acc", self.a_acc)?;
        positive("-a_dec", -self.a_dec)?;
        positive("sensor_range", self.sensor_range)?;
        positive("idm.min_gap", self.idm.min_gap)?;
        positive("idm.a_max", self.idm.a_max)?;
        positive("idm.b_comfort", self.idm.b_comfort)?;
        positive("idm.delta", self.idm.delta)?;
        positive("-idm.a_min", -self.idm.a_min)?;
        if !(self.idm.time_headway.is_finite() && self.idm.time_headway >= 0.0) {
            return Err(SimError::InvalidParameter {
                name: "idm.time_headway",
                reason: "must be finite and non-negative",
            });
        }
        positive("mobil.b_safe", self.mobil.b_safe)?;
        if !(self.mobil.politeness.is_finite() && self.mobil.threshold.is_finite()) {
            return Err(SimError::InvalidParameter {
                name: "mobil",
                reason: "politeness and threshold must be finite",
            });
        }
        self.sv.validate()?;
        // An SV's slowdown is a braking its vehicle has.
        if self.sv.gentle_decel > -self.idm.a_min {
            return Err(SimError::InvalidParameter {
                name: "sv.gentle_decel",
                reason: "must be at most the strongest braking -idm.a_min",
            });
        }
        Ok(())
    }
}
