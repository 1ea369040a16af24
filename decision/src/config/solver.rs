//! The `[solver]` section: which backend decides, and how HiGHS and the exact evaluation's LP
//! are run.

use serde::{Deserialize, Serialize};

/// Which backend solves the decision problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// The MILP on HiGHS.
    #[default]
    Milp,
    /// Exhaustive enumeration of the ego's action sequences (the exact oracle).
    Enumeration,
}

impl Backend {
    pub fn name(self) -> &'static str {
        match self {
            Backend::Milp => "milp",
            Backend::Enumeration => "enumeration",
        }
    }
}

/// Solver of the planner's small LPs: the exact evaluation's LP over one sequence's
/// accelerations, and the MILP relaxation's LPs in the branch and bound before the MIP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LpSolver {
    /// The dense dual simplex of the `dense_lp` crate (HiGHS when it gives no verdict).
    #[default]
    Dense,
    /// HiGHS, the reference.
    Highs,
}

/// Solver settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverSettings {
    pub backend: Backend,
    /// HiGHS `time_limit` per solve, s. HiGHS may overrun it by some milliseconds, and it is
    /// not checked in presolve; the service's watchdog enforces the real deadline.
    pub time_limit_s: f64,
    /// Offer HiGHS the best of the shifted previous plan and "keep everything" as incumbent.
    pub warm_start: bool,
    /// Solve each layer's LP relaxation first and skip the MIP run when it settles the
    /// layer (infeasible, bound reaching the incumbent, or an optimal integral / rounded
    /// plan). Exact either way; it saves HiGHS's per-MIP setup on most decisions.
    pub relaxation_first: bool,
    /// With `relaxation_first`: LP runs a small best-first branch and bound over the
    /// relaxation may spend before the layer goes to HiGHS's MIP (which costs a few ms of
    /// root work however small the model). Exact either way; 1 = the root relaxation only.
    pub branch_lps: usize,
    /// Tolerance when checking a plan against the exact constraints, m.
    pub feasibility_tolerance: f64,
    /// Solver of the exact evaluation's LP (`"dense"` or `"highs"`; same optimum).
    pub evaluation_lp: LpSolver,
    /// Solver of the LP relaxations in the small branch and bound (`"dense"`: the dense
    /// simplex with steepest-edge pricing and bound flipping, HiGHS when it gives no verdict;
    /// `"highs"`: HiGHS, the reference).
    pub tree_lp: LpSolver,
    /// Further HiGHS options by name (`[solver.highs_options]`, e.g. `mip_detect_symmetry =
    /// false`), set after the planner's own; an unknown name or a value of the wrong type
    /// fails `Planner::new`. The planner's settings (quiet, one thread, presolve off, time
    /// limit) can be overridden here too, at the user's risk.
    pub highs_options: std::collections::BTreeMap<String, HighsOptionValue>,
}

/// The value of one HiGHS option, as TOML writes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum HighsOptionValue {
    Bool(bool),
    Int(i64),
    Float(f64),
    Text(String),
}

impl std::fmt::Display for HighsOptionValue {
    /// The form `Highs_setOptionValue` parses.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HighsOptionValue::Bool(b) => write!(f, "{b}"),
            HighsOptionValue::Int(i) => write!(f, "{i}"),
            HighsOptionValue::Float(x) => write!(f, "{x:?}"),
            HighsOptionValue::Text(t) => f.write_str(t),
        }
    }
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            backend: Backend::Milp,
            time_limit_s: 0.3,
            warm_start: true,
            relaxation_first: true,
            branch_lps: 64,
            feasibility_tolerance: 1e-6,
            evaluation_lp: LpSolver::Dense,
            tree_lp: LpSolver::Dense,
            highs_options: std::collections::BTreeMap::new(),
        }
    }
}
