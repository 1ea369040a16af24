//! A small best-first branch and bound over the layer's LP relaxation, run before any HiGHS
//! MIP. HiGHS's MIP costs a few milliseconds of root work (cut loop, analytic centre,
//! heuristics) even when the root settles the model, while one relaxation costs about a
//! tenth of that. The relaxations of these models are tight (the optimum is usually within
//! a few per cent of the root bound), so a handful of branched LPs prove most layers that
//! the root alone leaves open. Past its LP budget the tree hands its best plan to the MIP
//! as the incumbent. Exact either way: a node is dropped only when it is infeasible, its
//! bound reaches the best exact cost, or its LP point is integral and scored.

use super::{decode, Columns};
use crate::config::LpSolver;
use crate::error::SolverError;
use crate::evaluate::{evaluate, evaluate_at, Evaluation, Mode};
use crate::highs_solver::{Bounds, HighsSolver, MipModel, MipResult, MipStatus};
use crate::problem::Problem;
use crate::small_lp::{FinalTableau, LpOutcome, Pricing, SmallLp};
use crate::types::Action;
use std::rc::Rc;

/// How far from an integer an integer column of the relaxation may be (HiGHS's default
/// `mip_feasibility_tolerance`).
const INTEGRALITY_TOLERANCE: f64 = 1e-6;

/// A plan within this (relative) of a bound is optimal.
const OPTIMALITY_TOLERANCE: f64 = 1e-6;

/// What the tree settled.
pub(super) enum Settled {
    /// The layer's optimum: the best plan, the warm incumbent included (`None`: no plan
    /// exists).
    Optimal(Option<Evaluation>),
    /// The LP budget ran out; the MIP must decide, with this best plan so far.
    Open(Option<Evaluation>),
}

/// What is known before the tree: the best warm candidate (a plan must cost no more to
/// replace it) and the sequences already scored exactly.
pub(super) struct WarmStart<'a> {
    pub incumbent: Option<Evaluation>,
    pub scored: &'a [Vec<Action>],
}

struct Node {
    bound: f64,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// The parent's final dense tableau, the child's start (shared by both children).
    start: Option<Rc<FinalTableau>>,
}

fn meets(bound: f64, cost: f64) -> bool {
    cost <= bound + OPTIMALITY_TOLERANCE * (1.0 + bound.abs())
}

/// The integer column to branch on: the most fractional, the earliest on ties (columns are
/// laid out step by step, so an early step's choice is split first).
fn branching_column(model: &MipModel, values: &[f64]) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (c, (&integer, &v)) in model.integer.iter().zip(values).enumerate() {
        let frac = (v - v.round()).abs();
        if integer && frac > INTEGRALITY_TOLERANCE && best.is_none_or(|(_, f)| frac > f + 1e-9) {
            best = Some((c, frac));
        }
    }
    best.map(|(c, _)| c)
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

/// One layer's node LPs: the dense simplex, or HiGHS (also when the dense one gives no
/// verdict). HiGHS's fixed cost per run (model checks, scaling, set-up, KKT report) is most
/// of its time on relaxations of this size; the dense tableau has none of it.
struct NodeLp<'a> {
    model: &'a MipModel,
    dense: Option<SmallLp>,
    highs: &'a mut HighsSolver,
    highs_loaded: bool,
}

impl<'a> NodeLp<'a> {
    fn new(model: &'a MipModel, tree: &'a mut TreeLp) -> Self {
        let small = model.num_rows() * model.num_cols() <= DENSE_MAX_ENTRIES;
        let dense = (tree.solver == LpSolver::Dense && small).then(|| dense_relaxation(model));
        Self {
            model,
            dense,
            highs: &mut tree.highs,
            highs_loaded: false,
        }
    }

    /// The relaxation within `bounds`, the dense one from the parent's final tableau
    /// `start`, with the final tableau to start the children from; with `objective_bound`,
    /// HiGHS may stop early and report `Infeasible` when the optimum cannot come below it.
    fn solve(
        &mut self,
        bounds: Bounds<'_>,
        start: Option<FinalTableau>,
        objective_bound: Option<f64>,
    ) -> Result<(MipResult, Option<FinalTableau>), SolverError> {
        if let Some(lp) = &mut self.dense {
            for (c, (&lo, &hi)) in bounds.lower.iter().zip(bounds.upper).enumerate() {
                lp.set_bounds(c, lo, hi);
            }
            match lp.solve_from(Pricing::SteepestEdge, start) {
                Ok((LpOutcome::Optimal { x, objective }, tableau)) => {
                    let result = MipResult {
                        status: MipStatus::Optimal,
                        objective,
                        columns: Some(x),
                        nodes: 0,
                    };
                    return Ok((result, tableau));
                }
                Ok((LpOutcome::Infeasible, _)) => return Ok((MipResult::nothing_found(), None)),
                Err(_) => {}
            }
        }
        if !self.highs_loaded {
            self.highs.load_relaxation(self.model)?;
            self.highs_loaded = true;
        }
        Ok((self.highs.resolve_within(bounds, objective_bound)?, None))
    }
}

/// `model`'s LP relaxation as a dense LP.
pub(super) fn dense_relaxation(model: &MipModel) -> SmallLp {
    let mut lp = SmallLp::default();
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
    let mut best = warm.incumbent;
    // Sequences already scored exactly (the warm candidates, then the nodes' roundings).
    let mut scored: Vec<Vec<Action>> = warm.scored.to_vec();
    let mut open = vec![Node {
        bound: f64::NEG_INFINITY,
        lower: model.col_lower.clone(),
        upper: model.col_upper.clone(),
        start: None,
    }];
    let mut node_lp = NodeLp::new(model, tree);
    let mut lps = 0;
    // The bound a node must beat: the best plan's cost.
    let target = |best: &Option<Evaluation>| best.as_ref().map(|e| e.cost);
    while let Some(at) = lowest(&open) {
        if target(&best).is_some_and(|t| meets(open[at].bound, t)) {
            break; // every open node is at least as costly as the best plan
        }
        if lps == max_lps.max(1) {
            return Ok(Settled::Open(best));
        }
        let mut node = open.swap_remove(at);
        // The parent's tableau, copied only while the sibling still needs it.
        let start = node
            .start
            .take()
            .map(|shared| Rc::try_unwrap(shared).unwrap_or_else(|shared| (*shared).clone()));
        let bounds = Bounds {
            lower: &node.lower,
            upper: &node.upper,
        };
        // A node that cannot beat the best plan may stop early: it is pruned either way.
        let (relaxed, tableau) = node_lp.solve(bounds, start, target(&best))?;
        lps += 1;
        let (bound, values) = match (relaxed.status, relaxed.columns) {
            (MipStatus::Infeasible, _) => continue,
            (MipStatus::Optimal, Some(values)) => (relaxed.objective, values),
            // Numerical trouble: leave the layer to the MIP.
            _ => return Ok(Settled::Open(best)),
        };
        if target(&best).is_some_and(|t| meets(bound, t)) {
            continue;
        }
        let (actions, accel) = decode(problem, cols, &values);
        let Some(column) = branching_column(model, &values) else {
            // Integral: this node's optimum is its LP point.
            match evaluate_at(problem, &actions, &accel, mode) {
                Some(e) => consider(&mut best, e),
                None => return Ok(Settled::Open(best)),
            }
            continue;
        };
        // The LP point's lane and beta choices rounded, at their own best accelerations.
        if !scored.contains(&actions) {
            if let Some(e) = evaluate(problem, &actions, mode) {
                consider(&mut best, e);
            }
            scored.push(actions);
            if target(&best).is_some_and(|t| meets(bound, t)) {
                continue;
            }
        }
        let start = tableau.map(Rc::new);
        let mut down = Node {
            bound,
            lower: node.lower.clone(),
            upper: node.upper.clone(),
            start: start.clone(),
        };
        down.upper[column] = values[column].floor();
        let mut up = node;
        up.bound = bound;
        up.start = start;
        up.lower[column] = values[column].ceil();
        open.push(down);
        open.push(up);
    }
    Ok(Settled::Optimal(best))
}

/// Index of the open node with the lowest bound (best first).
fn lowest(open: &[Node]) -> Option<usize> {
    (0..open.len()).min_by(|&a, &b| open[a].bound.total_cmp(&open[b].bound))
}

/// Keep `e` if it is the best plan so far (a later plan wins an exact tie, as a solver's plan
/// wins one against the warm incumbent).
fn consider(best: &mut Option<Evaluation>, e: Evaluation) {
    if best.as_ref().is_none_or(|b| e.cost <= b.cost) {
        *best = Some(e);
    }
}
