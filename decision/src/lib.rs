//! The HMDP-MPC decision core.
//!
//! Pure logic, no I/O and no transport: a [`Situation`] (road, ego state and maneuver,
//! perceived SVs, and the memory the last decision returned) goes in, a [`Decision`] (first
//! action, next maneuver, planned sequence, the layer that produced it, statistics and the
//! updated memory) comes out. See `docs/architecture.md` for how the pieces fit.
//!
//! Two backends solve the same problem: the MILP on HiGHS ([`Backend::Milp`]) and exhaustive
//! enumeration of the ego's action sequences ([`Backend::Enumeration`]), the exact oracle the
//! tests hold the MILP to.

// The configuration's sections are a namespace of their own (`decision::config::IdmParams`);
// the corpus is the tests' and benches' generator (feature `corpus`). Every other module is
// private: what the core offers is the list below.
mod braking_end;
pub mod config;
#[cfg(feature = "corpus")]
pub mod corpus;
mod enumeration;
mod error;
mod evaluate;
mod evidence;
mod fallback;
mod highs_cores;
mod highs_solver;
mod hysteresis;
mod idm;
mod lanes;
mod lp;
mod milp;
mod model;
mod plain_nominal;
mod planner;
mod problem;
mod scenario;
mod stopping;
mod types;
mod validate;

// The exact evaluation of one sequence and its acceleration LP, for the examples that
// measure them and the tests that hold the backends to them.
pub use config::{Backend, LateralDeparture, PlanOccupancy, PlannerConfig, RearDistance};
pub use enumeration::solve as solve_by_enumeration;
pub use error::{ConfigError, DecisionError, InputError, SolverError};
pub use evaluate::{accel_lp, evaluate, requirements, Evaluation, Mode};
pub use highs_solver::InterruptHandle;
pub use idm::idm_distance;
pub use lanes::{LaneSet, ROAD_EDGE_TOLERANCE_M};
pub use model::{admissible_sequences, rollout, Rollout};
pub use plain_nominal::{classify_nominal, NominalClass};
pub use planner::{fallback_only, Planner};
pub use problem::{prepare, Prepared, Problem, SvConstraint};
pub use types::{
    Action, CorrectiveEntry, Decision, EgoState, Layer, Maneuver, PlanStep, PlannerMemory, Road, SetPoint, Situation,
    SolveStats, SvObservation, Threat,
};
pub use validate::{ValidSituation, MAX_INPUT_SVS, NEGATIVE_SPEED_TOLERANCE_MPS};
