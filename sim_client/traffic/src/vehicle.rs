use serde::{Deserialize, Serialize};

use crate::{LaneChange, LaneSet, Road};

/// Who controls a vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum VehicleKind {
    /// The vehicle under test (id 0).
    Ego,
    /// A surrounding vehicle driven by IDM + MOBIL + random switches.
    Surrounding,
}

/// Full simulator state of one vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Vehicle {
    /// Unique id; the ego is 0.
    pub id: u32,
    /// Controller kind.
    pub kind: VehicleKind,
    /// Longitudinal position of the centre (m).
    pub x: f64,
    /// Lateral position of the centre (m).
    pub y: f64,
    /// Lateral velocity over the last step (m/s, positive = to the left).
    #[serde(default)]
    pub vy: f64,
    /// Speed (m/s), never negative.
    pub v: f64,
    /// Longitudinal acceleration applied during the last step (m/s^2).
    pub a: f64,
    /// Lane whose centre is nearest to `y`.
    pub lane: u8,
    /// Lane the vehicle is heading to (equals `lane` when not changing lanes).
    pub target_lane: u8,
    /// Lateral manoeuvre under way, if any.
    pub lane_change: Option<LaneChange>,
    /// Desired speed for IDM (m/s).
    pub desired_speed: f64,
    /// Longitudinal mode beta in {-1, 0, 1} (SVs: HMDP state; ego: last command).
    pub beta: i8,
}

impl Vehicle {
    /// Whether a lateral manoeuvre is under way.
    pub fn is_changing_lanes(&self) -> bool {
        self.lane_change.is_some()
    }

    /// Lane-change progress in `[0, 1]`, or `None` when driving in a lane.
    pub fn lane_change_progress(&self, dt: f64) -> Option<f64> {
        self.lane_change.map(|lc| lc.progress(dt))
    }

    /// Lanes in which the vehicle matters to others: the lanes its rectangle touches plus,
    /// during a lane change, every lane from origin to target.
    pub fn lane_set(&self, road: &Road) -> LaneSet {
        let mut s = road.lanes_occupied(self.y);
        s.insert(self.lane);
        if let Some(lc) = self.lane_change {
            s = s.union(LaneSet::span(lc.origin_lane, lc.target_lane));
        }
        s
    }
}
