use serde::{Deserialize, Serialize};

use crate::Road;

/// What the ego knows about itself.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EgoObservation {
    /// Longitudinal position (m).
    pub x: f64,
    /// Lateral position (m).
    pub y: f64,
    /// Speed (m/s).
    pub v: f64,
    /// Acceleration (m/s^2).
    pub a: f64,
    /// Lane whose centre is nearest to the ego.
    pub lane: u8,
    /// Lane the ego is heading to.
    pub target_lane: u8,
    /// Speed the ego wants to drive (m/s).
    pub desired_speed: f64,
}

/// A surrounding vehicle as a perception stack reports it: kinematics only, no intent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SvObservation {
    /// Track id (the vehicle id).
    pub id: u32,
    /// Longitudinal position (m).
    pub x: f64,
    /// Lateral position (m).
    pub y: f64,
    /// Speed (m/s).
    pub v: f64,
    /// Acceleration (m/s^2).
    pub a: f64,
    /// Lateral velocity (m/s, positive = to the left).
    #[serde(default)]
    pub vy: f64,
}

/// Snapshot handed to a planner at a decision instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Perception {
    /// Simulation time (s).
    pub time: f64,
    /// Road geometry and speed limit.
    pub road: Road,
    /// The ego's own state.
    pub ego: EgoObservation,
    /// SVs within sensor range, sorted by id.
    pub svs: Vec<SvObservation>,
}
