//! Best-first branch and bound over an LP relaxation, within a budget of LP runs.

use std::rc::Rc;

use crate::simplex::FinalTableau;

/// How far from an integer an integer column of a relaxation may be (HiGHS's default
/// `mip_feasibility_tolerance`).
pub const INTEGRALITY_TOLERANCE: f64 = 1e-6;

/// A plan within this (relative) of a bound is optimal.
pub const OPTIMALITY_TOLERANCE: f64 = 1e-6;

/// Column bounds of one node.
#[derive(Debug, Clone, Copy)]
pub struct Bounds<'a> {
    pub lower: &'a [f64],
    pub upper: &'a [f64],
}

/// A node's LP, as the search's solver ended it.
#[derive(Debug, Clone, PartialEq)]
pub enum Relaxed {
    Optimal {
        objective: f64,
        x: Vec<f64>,
    },
    /// No point, or none below the objective bound the node was given.
    Infeasible,
    /// No verdict (numerical trouble): the tree stops and leaves the problem open.
    Failed,
}

/// What the tree asks of the problem it searches.
pub trait Search {
    /// A solution scored exactly.
    type Plan;
    type Error;

    /// A plan's exact cost.
    fn cost(plan: &Self::Plan) -> f64;

    /// The relaxation within `bounds`, from `start` (the parent's final tableau) when there
    /// is one, with the final tableau to start the children from. With `objective_bound`
    /// the solver may stop early and report [`Relaxed::Infeasible`] when the optimum cannot
    /// come below it.
    fn relax(
        &mut self,
        bounds: Bounds<'_>,
        start: Option<FinalTableau>,
        objective_bound: Option<f64>,
    ) -> Result<(Relaxed, Option<FinalTableau>), Self::Error>;

    /// The plan at an integral LP point; `None` when it cannot be scored (the tree stops and
    /// leaves the problem open).
    fn integral(&mut self, x: &[f64]) -> Option<Self::Plan>;

    /// The plan of a fractional point's rounding; `None` when it is infeasible or was
    /// scored before.
    fn rounding(&mut self, x: &[f64]) -> Option<Self::Plan>;
}

/// The problem the tree searches: which columns are integer, the root's bounds, the
/// budget of LP runs.
#[derive(Debug, Clone, Copy)]
pub struct Tree<'a> {
    pub integer: &'a [bool],
    pub lower: &'a [f64],
    pub upper: &'a [f64],
    pub max_lps: usize,
}

/// What the tree settled.
#[derive(Debug, Clone, PartialEq)]
pub enum Settled<P> {
    /// The optimum: the best plan, the incumbent included (`None`: no plan exists).
    Optimal(Option<P>),
    /// The budget ran out, or a node gave no verdict: the best plan so far.
    Open(Option<P>),
}

struct Node {
    bound: f64,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// The parent's final tableau, the child's start (shared by both children).
    start: Option<Rc<FinalTableau>>,
}

fn meets(bound: f64, cost: f64) -> bool {
    cost <= bound + OPTIMALITY_TOLERANCE * (1.0 + bound.abs())
}

/// The integer column to branch on: the most fractional, the earliest on ties.
fn branching_column(integer: &[bool], values: &[f64]) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (c, (&integer, &v)) in integer.iter().zip(values).enumerate() {
        let frac = (v - v.round()).abs();
        if integer && frac > INTEGRALITY_TOLERANCE && best.is_none_or(|(_, f)| frac > f + 1e-9) {
            best = Some((c, frac));
        }
    }
    best.map(|(c, _)| c)
}

/// Index of the open node with the lowest bound (best first).
fn lowest(open: &[Node]) -> Option<usize> {
    (0..open.len()).min_by(|&a, &b| open[a].bound.total_cmp(&open[b].bound))
}

/// Keep `plan` if it is the best so far (a later plan wins an exact tie).
fn consider<S: Search>(best: &mut Option<S::Plan>, plan: S::Plan) {
    if best.as_ref().is_none_or(|b| S::cost(&plan) <= S::cost(b)) {
        *best = Some(plan);
    }
}

/// Search `tree` best first from `incumbent`: the open node of the lowest bound is solved,
/// its point scored (integral) or rounded and scored, and split on its most fractional
/// integer column; the children start from its final tableau. A node is dropped only when it
/// is infeasible, its bound reaches the best plan's cost, or its point is integral and
/// scored, so [`Settled::Optimal`] is exact.
pub fn best_first<S: Search>(
    search: &mut S,
    tree: Tree<'_>,
    incumbent: Option<S::Plan>,
) -> Result<Settled<S::Plan>, S::Error> {
    let mut best = incumbent;
    let mut open = vec![Node {
        bound: f64::NEG_INFINITY,
        lower: tree.lower.to_vec(),
        upper: tree.upper.to_vec(),
        start: None,
    }];
    let mut lps = 0;
    // The bound a node must beat: the best plan's cost.
    let target = |best: &Option<S::Plan>| best.as_ref().map(S::cost);
    while let Some(at) = lowest(&open) {
        if target(&best).is_some_and(|t| meets(open[at].bound, t)) {
            break; // every open node is at least as costly as the best plan
        }
        if lps == tree.max_lps.max(1) {
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
        let (relaxed, tableau) = search.relax(bounds, start, target(&best))?;
        lps += 1;
        let (bound, values) = match relaxed {
            Relaxed::Infeasible => continue,
            Relaxed::Optimal { objective, x } => (objective, x),
            Relaxed::Failed => return Ok(Settled::Open(best)),
        };
        if target(&best).is_some_and(|t| meets(bound, t)) {
            continue;
        }
        let Some(column) = branching_column(tree.integer, &values) else {
            // Integral: this node's optimum is its LP point.
            match search.integral(&values) {
                Some(plan) => consider::<S>(&mut best, plan),
                None => return Ok(Settled::Open(best)),
            }
            continue;
        };
        if let Some(plan) = search.rounding(&values) {
            consider::<S>(&mut best, plan);
        }
        if target(&best).is_some_and(|t| meets(bound, t)) {
            continue;
        }
        open.extend(split(node, bound, column, values[column], tableau));
    }
    Ok(Settled::Optimal(best))
}

/// The children of `node` (LP bound `bound`) on `column` at `value`: `column <= floor`, then
/// `column >= ceil`, both started from the node's final tableau.
fn split(node: Node, bound: f64, column: usize, value: f64, tableau: Option<FinalTableau>) -> [Node; 2] {
    let start = tableau.map(Rc::new);
    let mut down = Node {
        bound,
        lower: node.lower.clone(),
        upper: node.upper.clone(),
        start: start.clone(),
    };
    down.upper[column] = value.floor();
    let mut up = node;
    up.bound = bound;
    up.start = start;
    up.lower[column] = value.ceil();
    [down, up]
}
