use serde::{Deserialize, Serialize};

use crate::SimError;

/// Lane width (m) fixed by the shared conventions.
pub const LANE_WIDTH: f64 = 4.0;
/// Smallest supported lane count.
pub const MIN_LANES: u8 = 2;
/// Largest supported lane count.
pub const MAX_LANES: u8 = 5;
/// A vehicle further than this from its nearest lane centre also occupies the adjacent lane.
const OCCUPANCY_TOLERANCE: f64 = 0.1;

/// Straight multi-lane road; lane 1 is the leftmost (largest `y`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Road {
    /// Number of lanes, `2..=5`.
    pub lanes: u8,
    /// Lane width (m), 4 m by convention.
    pub lane_width: f64,
    /// Legal speed limit (m/s); the commanded ego never exceeds it.
    pub speed_limit: f64,
}

impl Road {
    /// A road with the conventional lane width; rejects lane counts outside `2..=5`.
    pub fn new(lanes: u8, speed_limit: f64) -> Result<Self, SimError> {
        let road = Road {
            lanes,
            lane_width: LANE_WIDTH,
            speed_limit,
        };
        road.validate()?;
        Ok(road)
    }

    /// Checks the invariants a hand-built `Road` literal might break.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(MIN_LANES..=MAX_LANES).contains(&self.lanes) {
            return Err(SimError::InvalidLaneCount(self.lanes));
        }
        if !(self.lane_width.is_finite() && self.lane_width > 0.0) {
            return Err(SimError::InvalidParameter {
                name: "lane_width",
                reason: "must be finite and positive",
            });
        }
        if !(self.speed_limit.is_finite() && self.speed_limit > 0.0) {
            return Err(SimError::InvalidParameter {
                name: "speed_limit",
                reason: "must be finite and positive",
            });
        }
        Ok(())
    }

    /// Whether `lane` is a valid index on this road.
    pub fn has_lane(&self, lane: u8) -> bool {
        (1..=self.lanes).contains(&lane)
    }

    /// Errors unless `lane` exists.
    pub fn check_lane(&self, lane: u8) -> Result<(), SimError> {
        if self.has_lane(lane) {
            Ok(())
        } else {
            Err(SimError::InvalidLane {
                lane,
                lanes: self.lanes,
            })
        }
    }

    /// Lateral position of the centre of `lane` (not range-checked).
    pub fn lane_centre(&self, lane: u8) -> f64 {
        (f64::from(self.lanes) - f64::from(lane)) * self.lane_width
    }

    /// Lane whose centre is nearest to `y`, clamped to the road.
    pub fn lane_of(&self, y: f64) -> u8 {
        let from_right = (y / self.lane_width).round();
        let lane = f64::from(self.lanes) - from_right;
        lane.clamp(1.0, f64::from(self.lanes)) as u8
    }

    /// Lanes a vehicle centred at `y` occupies: its nearest lane, plus the adjacent lane
    /// on the side it leans towards when it is more than 0.1 m off the centre.
    pub fn lanes_occupied(&self, y: f64) -> LaneSet {
        let lane = self.lane_of(y);
        let mut set = LaneSet::single(lane);
        let offset = y - self.lane_centre(lane);
        if offset.abs() > OCCUPANCY_TOLERANCE {
            // Positive offset = towards the left = smaller lane index.
            let neighbour = if offset > 0.0 {
                lane.checked_sub(1)
            } else {
                Some(lane + 1)
            };
            if let Some(n) = neighbour.filter(|&n| self.has_lane(n)) {
                set.insert(n);
            }
        }
        set
    }

    /// Existing neighbour lanes of `lane` (left first).
    pub fn neighbours(&self, lane: u8) -> impl Iterator<Item = u8> + '_ {
        [lane.checked_sub(1), lane.checked_add(1)]
            .into_iter()
            .flatten()
            .filter(move |&l| self.has_lane(l))
    }
}

/// Small set of lane indices (bit `i` = lane `i`), used for occupancy and leader search.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct LaneSet(u8);

impl LaneSet {
    /// The empty set.
    pub const EMPTY: LaneSet = LaneSet(0);

    /// A set holding one lane.
    pub fn single(lane: u8) -> Self {
        let mut s = Self::EMPTY;
        s.insert(lane);
        s
    }

    /// All lanes from `a` to `b` inclusive, in either order.
    pub fn span(a: u8, b: u8) -> Self {
        let mut s = Self::EMPTY;
        for l in a.min(b)..=a.max(b) {
            s.insert(l);
        }
        s
    }

    /// Adds `lane` (lanes above 7 cannot exist on a valid road and are ignored).
    pub fn insert(&mut self, lane: u8) {
        if lane < 8 {
            self.0 |= 1 << lane;
        }
    }

    /// Whether `lane` is in the set.
    pub fn contains(self, lane: u8) -> bool {
        lane < 8 && self.0 & (1 << lane) != 0
    }

    /// Union of two sets.
    pub fn union(self, other: LaneSet) -> LaneSet {
        LaneSet(self.0 | other.0)
    }

    /// Whether the sets share a lane.
    pub fn intersects(self, other: LaneSet) -> bool {
        self.0 & other.0 != 0
    }

    /// Number of lanes in the set.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// Whether the set is empty.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Lanes in increasing index order.
    pub fn iter(self) -> impl Iterator<Item = u8> {
        (0u8..8).filter(move |&l| self.contains(l))
    }
}
