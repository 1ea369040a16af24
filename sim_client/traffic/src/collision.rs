use serde::{Deserialize, Serialize};

use crate::{VEHICLE_LENGTH, VEHICLE_WIDTH};

/// Whether two axis-aligned vehicle rectangles centred at `a` and `b` overlap.
///
/// Touching edges do not count: a collision needs a positive overlap area.
pub fn rectangles_overlap(a: (f64, f64), b: (f64, f64)) -> bool {
    (a.0 - b.0).abs() < VEHICLE_LENGTH && (a.1 - b.1).abs() < VEHICLE_WIDTH
}

/// A pair of vehicles whose rectangles overlap at the end of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Collision {
    /// Smaller id of the pair.
    pub a: u32,
    /// Larger id of the pair.
    pub b: u32,
    /// Whether one of the two is the ego.
    pub involves_ego: bool,
    /// True when the pair did not overlap at the end of the previous step.
    pub first_contact: bool,
}
