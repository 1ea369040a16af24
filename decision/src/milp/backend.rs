//! The MILP backend: the warm candidates, the LP relaxation that settles most layers, and
//! the HiGHS MIP run for the rest.

use super::{build, decode, Columns};
use crate::config::SolverSettings;
use crate::error::SolverError;
use crate::evaluate::{evaluate, evaluate_at, Evaluation, Mode};
use crate::highs_solver::{with_thread_lp, HighsSolver, InterruptHandle, MipModel, MipResult, MipStatus};
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
    /// Settled without a MIP run: by the model's construction or its LP relaxation.
    pub settled_at_root: bool,
}

/// How far from an integer an integer column of the relaxation may be (HiGHS's default
/// `mip_feasibility_tolerance`).
const INTEGRALITY_TOLERANCE: f64 = 1e-6;

/// An incumbent within this of the relaxation's bound is optimal.
const OPTIMALITY_TOLERANCE: f64 = 1e-6;

/// What a layer's LP relaxation settles before any branching. Its optimum is a lower bound
/// on every plan's cost, so:
enum Relaxation {
    /// no plan beats the incumbent (or the cutoff): the relaxation is infeasible, or its bound
    /// already reaches the incumbent's exact cost;
    NothingBetter,
    /// this plan is optimal: the relaxation's own point when it is integral, or the rounding
    /// of its lane and beta choices when that plan's exact cost meets the bound;
    Optimal(Evaluation),
    /// the MILP must decide.
    Open,
}

/// The MILP backend: one long-lived HiGHS instance.
pub struct MilpBackend {
    solver: HighsSolver,
    /// Try the LP relaxation before the MIP (`solver.relaxation_first`).
    relaxation_first: bool,
}

impl MilpBackend {
    /// A backend with the settings' time limit and extra HiGHS options.
    pub fn new(settings: &SolverSettings) -> Result<Self, SolverError> {
        let mut solver = HighsSolver::new(settings.time_limit_s)?;
        for (name, value) in &settings.highs_options {
            solver.set_option(name, &value.to_string())?;
        }
        Ok(Self {
            solver,
            relaxation_first: settings.relaxation_first,
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

    /// What the LP relaxation alone settles (see [`Relaxation`]).
    fn settle_by_relaxation(
        &mut self,
        problem: &Problem,
        mode: Mode,
        built: &(MipModel, Columns),
        cutoff: Option<f64>,
        incumbent: Option<&Evaluation>,
    ) -> Result<Relaxation, SolverError> {
        let (model, cols) = built;
        let lp = with_thread_lp(|lp| lp.solve_relaxation(model))?;
        let (bound, values) = match (lp.status, lp.columns) {
            (MipStatus::Infeasible, _) => return Ok(Relaxation::NothingBetter),
            (MipStatus::Optimal, Some(values)) => (lp.objective, values),
            _ => return Ok(Relaxation::Open),
        };
        let meets_bound = |cost: f64| cost <= bound + OPTIMALITY_TOLERANCE * (1.0 + bound.abs());
        if cutoff.is_some_and(|c| bound >= c) || incumbent.is_some_and(|e| meets_bound(e.cost)) {
            return Ok(Relaxation::NothingBetter);
        }
        let (actions, accel) = decode(problem, cols, &values);
        if model.is_integral(&values, INTEGRALITY_TOLERANCE) {
            if let Some(e) = evaluate_at(problem, &actions, &accel, mode) {
                return Ok(Relaxation::Optimal(e));
            }
        }
        // The relaxation's lane and beta choices rounded, at their own best accelerations.
        match evaluate(problem, &actions, mode) {
            Some(e) if meets_bound(e.cost) => Ok(Relaxation::Optimal(e)),
            _ => Ok(Relaxation::Open),
        }
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
        let incumbent_offered = !warm.is_empty();
        let incumbent = warm
            .iter()
            .filter_map(|actions| evaluate(problem, actions, mode))
            .min_by(|a, b| a.cost.total_cmp(&b.cost));
        // HiGHS prunes with the cutoff (`objective_bound`). With the continuous input it was
        // seen to declare "nothing below the cutoff" on a model whose optimum lies well below
        // it (4.88 under a cutoff of 14.10), so there the incumbent only competes afterwards.
        // It is scored even when HiGHS proves optimality: near-ties between sequences are
        // decided by the exact score, and skipping it (6 % of the solve time) turned Case 1's
        // lane change behind SV3 into following SV2 to the end.
        let cutoff = incumbent
            .as_ref()
            .filter(|_| !problem.kin.is_continuous())
            .map(|e| e.cost + 1e-6 + 1e-9 * e.cost.abs());
        let settled = if self.relaxation_first {
            self.settle_by_relaxation(problem, mode, &built, cutoff, incumbent.as_ref())?
        } else {
            Relaxation::Open
        };
        let settled_at_root = !matches!(settled, Relaxation::Open);
        let (model, cols) = &built;
        let (result, found) = match settled {
            Relaxation::NothingBetter => (MipResult::nothing_found(), None),
            Relaxation::Optimal(e) => (MipResult::optimal_at_root(e.cost), Some(e)),
            Relaxation::Open => {
                let result = self.solver.solve(model, cutoff)?;
                let usable = matches!(result.status, MipStatus::Optimal | MipStatus::Stopped);
                let found = match (&result.columns, usable) {
                    (Some(values), true) => {
                        let (actions, accel) = decode(problem, cols, values);
                        evaluate_at(problem, &actions, &accel, mode)
                    }
                    _ => None,
                };
                (result, found)
            }
        };
        let stopped = result.status == MipStatus::Stopped;
        let solver_objective = found.as_ref().map(|_| result.objective);
        let evaluation = match (found, incumbent) {
            (Some(f), Some(i)) => Some(if i.cost < f.cost { i } else { f }),
            (found, incumbent) => found.or(incumbent),
        };
        Ok(LayerOutcome {
            solver_objective,
            evaluation,
            rows: model.num_rows(),
            columns: model.num_cols(),
            binaries: model.num_integers(),
            nodes: result.nodes,
            warm_start: cutoff.is_some() || incumbent_offered,
            stopped,
            settled_at_root,
        })
    }
}
