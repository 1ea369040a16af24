//! The MILP backend: the warm candidates, the LP relaxation and its small branch and bound
//! that settle most layers (`branch.rs`), and the HiGHS MIP run for the rest.

use super::branch::{self, Settled, TreeLp, WarmStart};
use super::{build, decode};
use crate::config::SolverSettings;
use crate::error::SolverError;
use crate::evaluate::{evaluate, evaluate_at, Evaluation, Mode};
use crate::highs_solver::{HighsSolver, InterruptHandle, MipResult, MipStatus};
use crate::problem::Problem;
use crate::types::Action;

/// Outcome of one layer's solve.
#[derive(Debug, Clone)]
pub struct LayerOutcome {
    /// The plan, re-scored exactly; `None` when the layer is infeasible or gave no plan.
    pub evaluation: Option<Evaluation>,
    pub solver_objective: Option<f64>,
    pub rows: usize,
    pub columns: usize,
    pub binaries: usize,
    pub nodes: u64,
    pub warm_start: bool,
    /// The solve stopped at its time limit or an interrupt.
    pub stopped: bool,
    /// Settled without a MIP run: by the model's construction or its LP relaxation (with
    /// the small branch and bound over it). Read by the tests that compare the tree, the
    /// root relaxation and the MIP.
    #[cfg_attr(not(test), allow(dead_code))]
    pub settled_at_root: bool,
}

/// The MILP backend: one long-lived HiGHS instance.
pub struct MilpBackend {
    solver: HighsSolver,
    /// The branch and bound's LP solvers (`solver.tree_lp`; HiGHS's instance has no time
    /// limit: its LP clock runs on across the runs of one instance, and these LPs end in
    /// microseconds).
    tree_lp: TreeLp,
    /// Try the LP relaxation before the MIP (`solver.relaxation_first`).
    relaxation_first: bool,
    /// LP runs the small branch and bound may spend before the MIP (`solver.branch_lps`).
    branch_lps: usize,
}

impl MilpBackend {
    /// A backend with the settings' time limit and extra HiGHS options.
    pub fn new(settings: &SolverSettings) -> Result<Self, SolverError> {
        let mut solver = HighsSolver::new(settings.time_limit_s)?;
        let mut tree_lp = HighsSolver::new(f64::INFINITY)?;
        // Both instances (the tree's LPs are most of the solve time), except the time limit:
        // HiGHS's LP clock runs on across the runs of one instance.
        for (name, value) in &settings.highs_options {
            solver.set_option(name, &value.to_string())?;
            if name != "time_limit" {
                tree_lp.set_option(name, &value.to_string())?;
            }
        }
        Ok(Self {
            solver,
            tree_lp: TreeLp {
                highs: tree_lp,
                solver: settings.tree_lp,
            },
            relaxation_first: settings.relaxation_first,
            branch_lps: settings.branch_lps,
        })
    }

    pub fn interrupt_handle(&self) -> InterruptHandle {
        self.solver.interrupt_handle()
    }

    pub fn next_solve_id(&self) -> u64 {
        self.solver.next_solve_id()
    }

    pub fn set_time_limit(&mut self, seconds: f64) -> Result<(), SolverError> {
        self.solver.set_time_limit(seconds)
    }

    /// Solve one layer. `warm` are candidate sequences; the best feasible one is the
    /// incumbent whose cost cuts off the search.
    pub fn solve(&mut self, problem: &Problem, mode: Mode, warm: &[Vec<Action>]) -> Result<LayerOutcome, SolverError> {
        let Ok(built) = build(problem, mode) else {
            return Ok(LayerOutcome {
                evaluation: None,
                solver_objective: None,
                rows: 0,
                columns: 0,
                binaries: 0,
                nodes: 0,
                warm_start: false,
                stopped: false,
                settled_at_root: true,
            });
        };
        // The best warm candidate bounds the search; if nothing beats it, it is the answer.
        // It is scored even when the search proves optimality: near-ties between sequences
        // are decided by the exact score, and skipping it (6 % of the solve time) turned
        // Case 1's lane change behind SV3 into following SV2 to the end.
        let incumbent_offered = !warm.is_empty();
        let incumbent = warm
            .iter()
            .filter_map(|actions| evaluate(problem, actions, mode))
            .min_by(|a, b| a.cost.total_cmp(&b.cost));
        let cutoff_of = |e: &Evaluation| e.cost + 1e-6 + 1e-9 * e.cost.abs();
        let settled = if self.relaxation_first {
            let start = WarmStart {
                incumbent,
                scored: warm,
            };
            branch::settle(&mut self.tree_lp, problem, mode, &built, start, self.branch_lps)?
        } else {
            Settled::Open(incumbent)
        };
        let (model, cols) = &built;
        let (result, evaluation, settled_at_root) = match settled {
            Settled::Optimal(best) => {
                let result = match &best {
                    Some(e) => MipResult::optimal_at_root(e.cost),
                    None => MipResult::nothing_found(),
                };
                (result, best, true)
            }
            Settled::Open(best) => {
                // HiGHS prunes with the cutoff (`objective_bound`). (With HiGHS's presolve on,
                // it once declared "nothing below the cutoff" on a continuous-input model
                // whose optimum lay below it; presolve is off.)
                let result = self.solver.solve(model, best.as_ref().map(cutoff_of))?;
                let usable = matches!(result.status, MipStatus::Optimal | MipStatus::Stopped);
                let found = match (&result.columns, usable) {
                    (Some(values), true) => {
                        let (actions, accel) = decode(problem, cols, values);
                        evaluate_at(problem, &actions, &accel, mode)
                    }
                    _ => None,
                };
                let evaluation = match (found, best) {
                    (Some(f), Some(b)) => Some(if b.cost < f.cost { b } else { f }),
                    (found, best) => found.or(best),
                };
                (result, evaluation, false)
            }
        };
        let stopped = result.status == MipStatus::Stopped;
        let solver_objective = evaluation
            .as_ref()
            .map(|e| if settled_at_root { e.cost } else { result.objective });
        Ok(LayerOutcome {
            solver_objective,
            evaluation,
            rows: model.num_rows(),
            columns: model.num_cols(),
            binaries: model.num_integers(),
            nodes: result.nodes,
            warm_start: incumbent_offered,
            stopped,
            settled_at_root,
        })
    }
}
