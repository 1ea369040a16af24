//! A small best-first branch and bound over the layer's LP relaxation, run before any HiGHS
//! MIP. HiGHS's MIP costs a few milliseconds of root work (cut loop, analytic centre,
//! heuristics) even when the root settles the model, while one relaxation costs about a
//! tenth of that. The relaxations of these models are tight (the optimum is usually within
//! a few per cent of the root bound), so a handful of branched LPs prove most layers that
//! the root alone leaves open. Past its LP budget the tree hands its best plan to the MIP
//! as the incumbent. Exact either way: a node is dropped only when it is infeasible, its
//! bound reaches the best exact cost, or its LP point is integral and scored.
//!
//! The tree is `dense_lp::best_first`; what is the planner's is here ([`Layer`]): a node's LP
//! on the dense simplex or on HiGHS, and the exact scoring of an integral point or of a
//! rounding not scored before.

use super::{decode, Columns};
use crate::config::LpSolver;
use crate::error::SolverError;
use crate::evaluate::{evaluate, evaluate_at, Evaluation, Mode};
use crate::highs_solver::{self, HighsSolver, MipModel, MipStatus};
use crate::problem::Problem;
use crate::types::Action;
use dense_lp::{best_first, Bounds, DenseLp, FinalTableau, LpOutcome, Pricing, Relaxed, Search, Tree};

/// What the tree settled: the layer's optimum (`Optimal`, the warm incumbent included;
/// `None`: no plan exists), or, past the LP budget, the best plan so far for the MIP
/// (`Open`).
pub(super) type Settled = dense_lp::Settled<Evaluation>;

/// What is known before the tree: the best warm candidate (a plan must cost no more to
/// replace it) and the sequences already scored exactly.
pub(super) struct WarmStart<'a> {
    pub incumbent: Option<Evaluation>,
    pub scored: &'a [Vec<Action>],
}

/// Largest relaxation (rows x columns) the dense simplex takes. A dense pivot costs that
/// many operations a few times over, while a HiGHS run costs about 0.35 ms whatever the
/// size (set-up, scaling, KKT report) plus cheap sparse iterations. The root's tableau
/// starts from scratch (tens of pivots); a child starts from its parent's (a few). On the
/// 0.1 campaign slice, 7,000 / 20,000 / 60,000 entries gave a mean solve of 0.48 / 0.29 /
/// 0.27 ms (most 4-lane layers at `H = 3` and `H = 6` single, about 255 x 212, fall
/// between); 250,000 (the combined actions at `H = 6`) doubled that cell's p50 and p99.
const DENSE_MAX_ENTRIES: usize = 60_000;

/// The tree's LP solvers, kept by the backend: HiGHS on an instance of its own (the nodes'
/// LPs keep their basis there between runs, while the exact evaluation of a rounded plan
/// runs on the thread's LP instance), and which one takes the small relaxations.
pub(super) struct TreeLp {
    pub highs: HighsSolver,
    pub solver: LpSolver,
}

/// One layer's search: its node LPs on the dense simplex, or on HiGHS (also when the dense
/// one gives no verdict; HiGHS's fixed cost per run, model checks, scaling, set-up, KKT
/// report, is most of its time on relaxations of this size, and the dense tableau has none of
/// it), and the exact scoring of the nodes' points.
struct Layer<'a> {
    problem: &'a Problem,
    mode: Mode,
    cols: &'a Columns,
    model: &'a MipModel,
    dense: Option<DenseLp>,
    highs: &'a mut HighsSolver,
    highs_loaded: bool,
    /// Sequences already scored exactly (the warm candidates, then the nodes' roundings).
    scored: Vec<Vec<Action>>,
}

impl Search for Layer<'_> {
    type Plan = Evaluation;
    type Error = SolverError;

    fn cost(plan: &Evaluation) -> f64 {
        plan.cost
    }

    fn relax(
        &mut self,
        bounds: Bounds<'_>,
        start: Option<FinalTableau>,
        objective_bound: Option<f64>,
    ) -> Result<(Relaxed, Option<FinalTableau>), SolverError> {
        if let Some(lp) = &mut self.dense {
            for (c, (&lo, &hi)) in bounds.lower.iter().zip(bounds.upper).enumerate() {
                lp.set_bounds(c, lo, hi);
            }
            match lp.solve_from(Pricing::SteepestEdge, start) {
                Ok((LpOutcome::Optimal { x, objective }, tableau)) => {
                    return Ok((Relaxed::Optimal { objective, x }, tableau));
                }
                Ok((LpOutcome::Infeasible, _)) => return Ok((Relaxed::Infeasible, None)),
                Err(_) => {}
            }
        }
        if !self.highs_loaded {
            self.highs.load_relaxation(self.model)?;
            self.highs_loaded = true;
        }
        let bounds = highs_solver::Bounds {
            lower: bounds.lower,
            upper: bounds.upper,
        };
        let result = self.highs.resolve_within(bounds, objective_bound)?;
        let relaxed = match (result.status, result.columns) {
            (MipStatus::Infeasible, _) => Relaxed::Infeasible,
            (MipStatus::Optimal, Some(x)) => Relaxed::Optimal {
                objective: result.objective,
                x,
            },
            _ => Relaxed::Failed,
        };
        Ok((relaxed, None))
    }

    /// An integral node's optimum is its LP point.
    fn integral(&mut self, x: &[f64]) -> Option<Evaluation> {
        let (actions, accel) = decode(self.problem, self.cols, x);
        evaluate_at(self.problem, &actions, &accel, self.mode)
    }

    /// The LP point's lane and beta choices rounded, at their own best accelerations.
    fn rounding(&mut self, x: &[f64]) -> Option<Evaluation> {
        let (actions, _) = decode(self.problem, self.cols, x);
        if self.scored.contains(&actions) {
            return None;
        }
        let plan = evaluate(self.problem, &actions, self.mode);
        self.scored.push(actions);
        plan
    }
}

/// `model`'s LP relaxation as a dense LP.
pub(super) fn dense_relaxation(model: &MipModel) -> DenseLp {
    let mut lp = DenseLp::default();
    for c in 0..model.num_cols() {
        lp.add_col(model.col_cost[c], model.col_lower[c], model.col_upper[c]);
    }
    let mut terms = Vec::new();
    for r in 0..model.num_rows() {
        let start = model.row_start[r] as usize;
        let end = model
            .row_start
            .get(r + 1)
            .map_or(model.row_index.len(), |&e| e as usize);
        terms.clear();
        terms.extend((start..end).map(|i| (model.row_index[i] as usize, model.row_value[i])));
        lp.add_row(model.row_lower[r], model.row_upper[r], &terms);
    }
    lp
}

/// Settle a layer by branch and bound over its relaxation, within `max_lps` LP runs on
/// `tree`.
pub(super) fn settle(
    tree: &mut TreeLp,
    problem: &Problem,
    mode: Mode,
    built: &(MipModel, Columns),
    warm: WarmStart<'_>,
    max_lps: usize,
) -> Result<Settled, SolverError> {
    let (model, cols) = built;
    let small = model.num_rows() * model.num_cols() <= DENSE_MAX_ENTRIES;
    let mut layer = Layer {
        problem,
        mode,
        cols,
        model,
        dense: (tree.solver == LpSolver::Dense && small).then(|| dense_relaxation(model)),
        highs: &mut tree.highs,
        highs_loaded: false,
        scored: warm.scored.to_vec(),
    };
    let search = Tree {
        integer: &model.integer,
        lower: &model.col_lower,
        upper: &model.col_upper,
        max_lps,
    };
    best_first(&mut layer, search, warm.incumbent)
}
