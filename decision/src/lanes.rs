//! Lane occupancy as a bit set, and the geometry that maps a lateral position to lanes.

use crate::types::Road;

/// A set of lanes; bit `l - 1` stands for lane `l`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct LaneSet(pub u16);

impl LaneSet {
    pub const EMPTY: LaneSet = LaneSet(0);

    pub fn single(lane: u8) -> Self {
        LaneSet(1 << (lane - 1))
    }

    pub fn with(self, lane: u8) -> Self {
        LaneSet(self.0 | (1 << (lane - 1)))
    }

    pub fn without(self, lane: u8) -> Self {
        LaneSet(self.0 & !(1 << (lane - 1)))
    }

    pub fn union(self, other: LaneSet) -> Self {
        LaneSet(self.0 | other.0)
    }

    pub fn contains(self, lane: u8) -> bool {
        self.0 & (1 << (lane - 1)) != 0
    }

    pub fn intersects(self, other: LaneSet) -> bool {
        self.0 & other.0 != 0
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Lanes in increasing order.
    pub fn iter(self) -> impl Iterator<Item = u8> {
        (1..=16u8).filter(move |&l| self.contains(l))
    }
}

/// Fractional 0-based lane position of a lateral coordinate: lane `l` sits at `l - 1`.
fn lane_position(road: &Road, y: f64) -> f64 {
    f64::from(road.lanes) - 1.0 - y / road.lane_width_m
}

/// How far beyond the road edge a vehicle centre may be reported and still count as on its
/// outermost lane: a measurement, not an error (m).
pub const ROAD_EDGE_TOLERANCE_M: f64 = 1.0;

/// The lane whose centre is nearest to `y`, or `Err(nearest index)` when `y` is off the road
/// (more than half a lane plus [`ROAD_EDGE_TOLERANCE_M`] beyond the outermost centres).
pub fn nearest_lane(road: &Road, y: f64) -> Result<u8, i64> {
    let pos = lane_position(road, y);
    // Saturating: a coordinate far off the road must give an error, not an overflow.
    let nearest = (pos.round() as i64).saturating_add(1);
    let edge = 0.5 + ROAD_EDGE_TOLERANCE_M / road.lane_width_m;
    if pos < -edge || pos > f64::from(road.lanes) - 1.0 + edge {
        return Err(nearest);
    }
    Ok(nearest.clamp(1, i64::from(road.lanes)) as u8)
}

/// Lanes a vehicle at `y` occupies: its nearest lane when within `tolerance` of that centre,
/// otherwise both lanes it lies between (a lane change under way).
pub fn lanes_at(road: &Road, y: f64, tolerance: f64) -> Result<LaneSet, i64> {
    let nearest = nearest_lane(road, y)?;
    if (y - road.lane_centre(nearest)).abs() <= tolerance {
        return Ok(LaneSet::single(nearest));
    }
    let pos = lane_position(road, y);
    let lo = (pos.floor() as i64).saturating_add(1).clamp(1, i64::from(road.lanes)) as u8;
    let hi = (pos.ceil() as i64).saturating_add(1).clamp(1, i64::from(road.lanes)) as u8;
    Ok(LaneSet::single(lo).with(hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn road(lanes: u8) -> Road {
        Road {
            lanes,
            lane_width_m: 4.0,
            speed_limit_mps: 30.0,
        }
    }

    #[test]
    fn lane_one_is_leftmost_with_largest_y() {
        let r = road(2);
        assert_eq!(nearest_lane(&r, 4.0), Ok(1));
        assert_eq!(nearest_lane(&r, 0.0), Ok(2));
        assert_eq!(r.lane_centre(1), 4.0);
    }

    #[test]
    fn between_centres_occupies_both() {
        let r = road(3);
        assert_eq!(lanes_at(&r, 8.0, 0.1), Ok(LaneSet::single(1)));
        assert_eq!(lanes_at(&r, 6.0, 0.1), Ok(LaneSet::single(1).with(2)));
        assert_eq!(lanes_at(&r, 4.05, 0.1), Ok(LaneSet::single(2)));
        assert_eq!(lanes_at(&r, 3.5, 0.1), Ok(LaneSet::single(2).with(3)));
        // Off-centre outwards on the outermost lane: still one lane.
        assert_eq!(lanes_at(&r, -1.0, 0.1), Ok(LaneSet::single(3)));
    }

    #[test]
    fn off_road_is_an_error() {
        let r = road(2);
        // Two lanes of 4 m: the road spans y in [-2, 6]; 1 m beyond an edge is tolerated.
        assert!(nearest_lane(&r, -3.1).is_err());
        assert!(nearest_lane(&r, 7.1).is_err());
        assert_eq!(nearest_lane(&r, 6.9), Ok(1));
        assert_eq!(nearest_lane(&r, -2.9), Ok(2));
        assert!(nearest_lane(&r, 5.9).is_ok());
    }

    #[test]
    fn set_operations() {
        let a = LaneSet::single(1).with(3);
        assert!(a.contains(3) && !a.contains(2));
        assert!(a.intersects(LaneSet::single(3)));
        assert!(!a.intersects(LaneSet::single(2)));
        assert_eq!(a.iter().collect::<Vec<_>>(), vec![1, 3]);
    }
}
