//! A small best-first branch and bound over the layer's LP relaxation, run before any HiGHS
//! MIP. HiGHS's MIP costs a few milliseconds of root work (cut loop, analytic centre,
//! heuristics) even when the root settles the model, while one relaxation costs about a
//! tenth of that. The relaxations of these models are tight (the optimum is usually within
//! a few per cent of the root bound), so a handful of branched LPs prove most layers that
//! the root alone leaves open. Past its LP budget the tree hands its best plan to the MIP
//! as the incumbent. Exact either way: a node is dropped only when it is infeasible, its
//! bound reaches the best exact cost, or its LP point is integral and scored.

use super::{decode, Columns};
use crate::error::SolverError;
use crate::evaluate::{evaluate, evaluate_at, Evaluation, Mode};
use crate::highs_solver::{Bounds, HighsSolver, MipModel, MipStatus};
use crate::problem::Problem;
use crate::types::Action;

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

/// Settle a layer by branch and bound over its relaxation, within `max_lps` LP runs on `lp`
/// (an instance of its own: the nodes' LPs keep their basis there between runs, while the
/// exact evaluation of a rounded plan runs on the thread's LP instance).
pub(super) fn settle(
    lp: &mut HighsSolver,
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
    }];
    lp.load_relaxation(model)?;
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
        let node = open.swap_remove(at);
        let bounds = Bounds {
            lower: &node.lower,
            upper: &node.upper,
        };
        // A node that cannot beat the best plan may stop early: it is pruned either way.
        let relaxed = lp.resolve_within(bounds, target(&best))?;
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
        let mut down = Node {
            bound,
            lower: node.lower.clone(),
            upper: node.upper.clone(),
        };
        down.upper[column] = values[column].floor();
        let mut up = node;
        up.bound = bound;
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
