#![warn(missing_docs)]
//! Deterministic multi-lane traffic simulator for evaluating a driving decision planner.
//!
//! The crate is pure: no I/O, no threads, no global state. All randomness comes from
//! `ChaCha8Rng` streams seeded with a `u64`, so the same seed gives bit-identical runs.
//!
//! Conventions shared with the planner: SI units, positions are vehicle centres, vehicles
//! are [`VEHICLE_LENGTH`] x [`VEHICLE_WIDTH`] rectangles, lane 1 is the leftmost lane and
//! lane `i` of `n` has its centre at `y = (n - i) * lane_width`.

mod collision;
mod error;
mod idm;
mod lateral;
mod longitudinal;
mod mobil;
mod params;
mod perception;
mod road;
mod scenario;
mod vehicle;
mod world;

pub use collision::{rectangles_overlap, Collision};
pub use error::SimError;
pub use idm::{idm_acceleration, IdmParams};
pub use lateral::{smooth_profile, LaneChange};
pub use longitudinal::jerk_limited_acceleration;
pub use mobil::{mobil_evaluate, MobilDecision, MobilInput, MobilParams};
pub use params::{SimParams, SvBehaviour};
pub use perception::{EgoObservation, Perception, SvObservation};
pub use road::{LaneSet, Road, LANE_WIDTH, MAX_LANES, MIN_LANES};
pub use scenario::{PaperTableEntry, Scenario, TrafficConfig, VehicleInit};
pub use vehicle::{Vehicle, VehicleKind};
pub use world::{EgoCommand, EgoMode, World, WorldSnapshot};

/// Vehicle length (m); longitudinal gap is `|x_a - x_b| - VEHICLE_LENGTH`.
pub const VEHICLE_LENGTH: f64 = 5.0;
/// Vehicle width (m).
pub const VEHICLE_WIDTH: f64 = 2.0;
/// Id reserved for the ego vehicle; surrounding vehicles use `1..`.
pub const EGO_ID: u32 = 0;
