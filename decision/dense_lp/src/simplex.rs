//! The dense bounded-variable dual simplex: the LP, its solve and its errors.

use crate::tableau::Tableau;

/// Feasibility tolerance on a basic variable's bounds (rows carry metres and m/s).
pub const PRIMAL_TOL: f64 = 1e-9;
/// Smallest tableau entry that may be pivoted on.
pub(crate) const PIVOT_TOL: f64 = 1e-9;
/// What the point may violate an original row or bound by after the pivots, absolute.
pub const CHECK_TOL: f64 = 1e-7;
/// Ratios this close count as tied.
pub(crate) const RATIO_TIE: f64 = 1e-12;
/// Pivots between recomputations of the basic values (carried along in between).
const REFRESH_EVERY: usize = 16;

/// Why the dense simplex gave no verdict (a caller may then ask another solver).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Error {
    /// A column whose cost pushes it towards an infinite bound: no dual feasible start.
    #[error("column {0} has no finite bound on the side its cost prefers")]
    NoDualStart(usize),
    #[error("no optimum within {0} pivots")]
    PivotLimit(usize),
    /// The final point misses an original row or bound by more than [`CHECK_TOL`].
    #[error("the final point violates {0} beyond tolerance")]
    Inaccurate(Violated),
}

/// The row or column a check found violated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Violated {
    Row(usize),
    Column(usize),
}

impl std::fmt::Display for Violated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Violated::Row(r) => write!(f, "row {r}"),
            Violated::Column(c) => write!(f, "column {c}"),
        }
    }
}

/// How the dual simplex picks its pivots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pricing {
    /// The most violated row leaves, the smallest dual ratio enters (for LPs of a handful
    /// of columns).
    #[default]
    LargestViolation,
    /// Dual steepest edge (exact weights, read off the tableau) with the bound-flipping
    /// ratio test: boxed columns whose ratio comes first jump to their other bound instead
    /// of entering, as long as the leaving row stays violated. On relaxations whose columns
    /// are mostly `[0, 1]` boxes that takes several times fewer pivots.
    SteepestEdge,
}

/// The final tableau of an optimal solve (see [`DenseLp::solve_from`]).
#[derive(Clone)]
pub struct FinalTableau(pub(crate) Tableau);

/// How a solve ended.
#[derive(Debug, Clone, PartialEq)]
pub enum LpOutcome {
    Optimal { x: Vec<f64>, objective: f64 },
    Infeasible,
}

/// `min offset + cost . x` subject to `row_lower <= A x <= row_upper`, `lower <= x <= upper`.
#[derive(Debug, Clone, Default)]
pub struct DenseLp {
    offset: f64,
    pub(crate) cost: Vec<f64>,
    pub(crate) lower: Vec<f64>,
    pub(crate) upper: Vec<f64>,
    pub(crate) row_lower: Vec<f64>,
    pub(crate) row_upper: Vec<f64>,
    row_start: Vec<usize>,
    terms: Vec<(usize, f64)>,
}

impl DenseLp {
    #[inline]
    pub fn add_col(&mut self, cost: f64, lower: f64, upper: f64) -> usize {
        self.cost.push(cost);
        self.lower.push(lower);
        self.upper.push(upper);
        self.cost.len() - 1
    }

    /// Add `cost` to the objective coefficient of `col`.
    #[inline]
    pub fn add_cost(&mut self, col: usize, cost: f64) {
        self.cost[col] += cost;
    }

    /// Add a constant to the objective.
    #[inline]
    pub fn add_constant(&mut self, value: f64) {
        self.offset += value;
    }

    /// Add `lower <= sum(coef * col) <= upper`; repeated columns add up.
    #[inline]
    pub fn add_row(&mut self, lower: f64, upper: f64, terms: &[(usize, f64)]) {
        self.row_start.push(self.terms.len());
        self.terms.extend_from_slice(terms);
        self.row_lower.push(lower);
        self.row_upper.push(upper);
    }

    #[inline]
    pub fn num_cols(&self) -> usize {
        self.cost.len()
    }

    #[inline]
    pub fn num_rows(&self) -> usize {
        self.row_lower.len()
    }

    #[inline]
    pub fn cost(&self, col: usize) -> f64 {
        self.cost[col]
    }

    #[inline]
    pub fn bounds(&self, col: usize) -> (f64, f64) {
        (self.lower[col], self.upper[col])
    }

    #[inline]
    pub fn row_bounds(&self, row: usize) -> (f64, f64) {
        (self.row_lower[row], self.row_upper[row])
    }

    #[inline]
    pub fn row_terms(&self, row: usize) -> &[(usize, f64)] {
        let end = self.row_start.get(row + 1).copied().unwrap_or(self.terms.len());
        &self.terms[self.row_start[row]..end]
    }

    #[inline]
    pub fn objective_constant(&self) -> f64 {
        self.offset
    }

    /// `A x` of one row.
    #[inline]
    pub fn activity(&self, row: usize, x: &[f64]) -> f64 {
        self.row_terms(row).iter().map(|&(c, a)| a * x[c]).sum()
    }

    /// The objective at `x`.
    #[inline]
    pub fn objective(&self, x: &[f64]) -> f64 {
        self.offset + self.cost.iter().zip(x).map(|(c, x)| c * x).sum::<f64>()
    }

    /// Replace the box of `col`.
    #[inline]
    pub fn set_bounds(&mut self, col: usize, lower: f64, upper: f64) {
        self.lower[col] = lower;
        self.upper[col] = upper;
    }

    /// Solve by the dual simplex; see the module documentation.
    pub fn solve(&self) -> Result<LpOutcome, Error> {
        self.solve_with(Pricing::LargestViolation)
    }

    /// Solve by the dual simplex with the given pivot rules.
    pub fn solve_with(&self, pricing: Pricing) -> Result<LpOutcome, Error> {
        self.solve_from(pricing, None).map(|(outcome, _)| outcome)
    }

    /// Solve from `start`, the final tableau of this LP under other bounds (a branch and
    /// bound's parent node), or from a fresh tableau. The reduced costs carry over, so the
    /// dual simplex only repairs what the new bounds broke: a few pivots instead of tens.
    /// An optimum comes with its final tableau, the start for the next re-solve.
    pub fn solve_from(
        &self,
        pricing: Pricing,
        start: Option<FinalTableau>,
    ) -> Result<(LpOutcome, Option<FinalTableau>), Error> {
        let restarted = start.and_then(|FinalTableau(mut t)| t.restart(self).then_some(t));
        let mut tableau = match restarted {
            Some(t) => t,
            None => Tableau::new(self)?,
        };
        let (m, n) = tableau.size();
        let limit = 50 * (m + n) + 200;
        // Largest-violation pivoting is faster; Bland's rule past this point cannot cycle.
        let bland_after = 4 * (m + n) + 20;
        // Steepest edge carries the basic values through its pivots (the largest-violation rule
        // recomputes them every time, as it always has); optimality and infeasibility are
        // only declared on recomputed ones.
        let carried = pricing == Pricing::SteepestEdge;
        let mut since_refresh = REFRESH_EVERY;
        for iteration in 0..limit {
            let bland = iteration >= bland_after;
            let steepest = carried && !bland;
            if !steepest || since_refresh >= REFRESH_EVERY {
                tableau.update_basic_values(pricing);
                since_refresh = 0;
            }
            let choose = |t: &Tableau| {
                if steepest {
                    t.leaving_steepest()
                } else {
                    t.leaving(bland)
                }
            };
            let mut leaving = choose(&tableau);
            if leaving.is_none() && since_refresh > 0 {
                tableau.update_basic_values(pricing);
                since_refresh = 0;
                leaving = choose(&tableau);
            }
            let Some(p) = leaving else {
                let outcome = self.finish(&tableau)?;
                return Ok((outcome, Some(FinalTableau(tableau))));
            };
            let entering = if steepest {
                tableau.entering_flipping(p)
            } else {
                tableau.entering(p, bland)
            };
            let Some(q) = entering else {
                if since_refresh > 0 {
                    since_refresh = REFRESH_EVERY;
                    continue;
                }
                return Ok((LpOutcome::Infeasible, None));
            };
            tableau.pivot(p, q);
            since_refresh += 1;
        }
        Err(Error::PivotLimit(limit))
    }

    /// Read the point off the final tableau and check it against the original data.
    fn finish(&self, t: &Tableau) -> Result<LpOutcome, Error> {
        let n = self.num_cols();
        let mut x = vec![0.0; n];
        for (k, &v) in t.nonbasic.iter().enumerate() {
            if v < n {
                x[v] = t.value[k];
            }
        }
        for (i, &v) in t.basic.iter().enumerate() {
            if v < n {
                // Within PRIMAL_TOL of the box: put it inside, the rows move by less.
                x[v] = t.beta[i].clamp(self.lower[v], self.upper[v]);
            }
        }
        for (c, &v) in x.iter().enumerate() {
            if !(v >= self.lower[c] - CHECK_TOL && v <= self.upper[c] + CHECK_TOL) {
                return Err(Error::Inaccurate(Violated::Column(c)));
            }
        }
        for r in 0..self.num_rows() {
            let a = self.activity(r, &x);
            if !(a >= self.row_lower[r] - CHECK_TOL && a <= self.row_upper[r] + CHECK_TOL) {
                return Err(Error::Inaccurate(Violated::Row(r)));
            }
        }
        let objective = self.objective(&x);
        Ok(LpOutcome::Optimal { x, objective })
    }
}
