//! Typed errors of the decision core.

use thiserror::Error;

/// Why a situation was rejected before any solving.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum InputError {
    #[error("field `{field}` is not a finite number")]
    NonFinite { field: &'static str },
    #[error("field `{field}` = {value} is outside the plausible range [{min}, {max}]")]
    OutOfRange {
        field: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("field `{field}` is a negative speed ({value})")]
    NegativeSpeed { field: &'static str, value: f64 },
    #[error("road must have 1..={max} lanes, got {lanes}")]
    LaneCount { lanes: u8, max: u8 },
    /// `field` is the dotted path of the offending value (`ego.maneuver.lane`, `ego.y_m`,
    /// `sv.y_m`): the wire reports it as is.
    #[error("field `{field}`: lane {lane} is outside 1..={lanes}")]
    LaneOutOfRange { field: &'static str, lane: i64, lanes: u8 },
    #[error("field `{field}`: longitudinal state {beta} is outside -1..=1")]
    BetaOutOfRange { field: &'static str, beta: i8 },
    #[error("SV id {id} appears more than once")]
    DuplicateSvId { id: u32 },
    #[error("{count} SVs exceed the input capacity of {capacity}")]
    TooManyVehicles { count: usize, capacity: usize },
    /// `field` is `memory.corrective` or `memory.previous_plan`.
    #[error("planner memory `{field}` is invalid: {why}")]
    InvalidMemory { field: &'static str, why: &'static str },
}

/// A configuration that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    #[error("cannot parse planner config: {0}")]
    Parse(String),
    #[error("invalid planner config `{field}`: {why}")]
    Invalid { field: &'static str, why: &'static str },
}

/// Failure of the solver machinery itself (not infeasibility, which the layers handle).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SolverError {
    #[error("HiGHS call `{call}` failed with status {status}")]
    Highs { call: &'static str, status: i32 },
    #[error("HiGHS rejected option `{name}` = `{value}` (unknown name or wrong type)")]
    Option { name: String, value: String },
}

/// Anything `Planner::decide` can return instead of a decision.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DecisionError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Solver(#[from] SolverError),
}
