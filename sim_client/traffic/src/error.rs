use thiserror::Error;

/// Everything that can go wrong when building or driving a [`crate::World`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimError {
    /// The road must have between [`crate::MIN_LANES`] and [`crate::MAX_LANES`] lanes.
    #[error("lane count {0} outside 2..=5")]
    InvalidLaneCount(u8),
    /// A lane index outside `1..=lanes`.
    #[error("lane {lane} does not exist on a {lanes}-lane road")]
    InvalidLane {
        /// The offending lane index.
        lane: u8,
        /// Lanes on the road.
        lanes: u8,
    },
    /// Longitudinal mode must be -1, 0 or +1.
    #[error("beta {0} outside -1..=1")]
    InvalidBeta(i8),
    /// A numeric parameter is out of its admissible range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// What is expected of it.
        reason: &'static str,
    },
    /// Two vehicles of a scenario start with overlapping rectangles.
    #[error("vehicles {a} and {b} overlap in the initial state")]
    InitialOverlap {
        /// Smaller id.
        a: u32,
        /// Larger id.
        b: u32,
    },
    /// Random placement could not find a free spot for a vehicle.
    #[error("could not place vehicle {vehicle} after {retries} attempts")]
    PlacementFailed {
        /// Vehicle id (0 = ego).
        vehicle: u32,
        /// Attempts made.
        retries: u32,
    },
    /// `set_ego_command` was called while the ego drives itself (IDM + MOBIL).
    #[error("the ego is not in commanded mode")]
    EgoNotCommanded,
}
