use serde::{Deserialize, Serialize};

use crate::Road;

/// What the ego knows about itself.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EgoObservation {
    pub x: f64,
    pub y: f64,
    pub v: f64,
    pub a: f64,
    /// Lane whose centre is nearest to the ego.
    pub lane: u8,
    /// Lane the ego is heading to.
    pub target_lane: u8,
    pub desired_speed: f64,
}

/// A surrounding vehicle as a perception stack reports it: kinematics only, no intent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SvObservation {
    pub id: u32,
    pub x: f64,
    pub y: f64,
    pub v: f64,
    pub a: f64,
}

/// Snapshot handed to a planner at a decision instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Perception {
    /// Simulation time (s).
    pub time: f64,
    pub road: Road,
    pub ego: EgoObservation,
    /// SVs within sensor range, sorted by id.
    pub svs: Vec<SvObservation>,
}
