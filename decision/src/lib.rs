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

pub mod config;
#[cfg(feature = "corpus")]
pub mod corpus;
pub mod enumeration;
pub mod error;
pub mod evaluate;
pub mod evidence;
pub mod fallback;
mod highs_cores;
pub mod highs_solver;
pub mod hysteresis;
pub mod idm;
pub mod lanes;
pub mod lp;
pub mod milp;
pub mod model;
pub mod plain_nominal;
pub mod planner;
pub mod problem;
pub mod scenario;
pub mod types;
pub mod validate;

pub use config::{Backend, LateralDeparture, PlannerConfig};
pub use error::{ConfigError, DecisionError, InputError, SolverError};
pub use highs_solver::InterruptHandle;
pub use plain_nominal::{classify_nominal, NominalClass};
pub use planner::{fallback_only, Planner};
pub use types::{
    Action, CorrectiveEntry, Decision, EgoState, Layer, Maneuver, PlanStep, PlannerMemory, Road, SetPoint, Situation,
    SolveStats, SvObservation, Threat,
};
pub use validate::{ValidSituation, MAX_INPUT_SVS, NEGATIVE_SPEED_TOLERANCE_MPS};
