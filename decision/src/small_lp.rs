//! A dense bounded-variable dual simplex for the exact evaluation's LP.
//!
//! That LP has at most `H <= 6` boxed accelerations, a few non-negative auxiliary columns
//! with non-negative costs and some tens of rows once the rows a box already satisfies are
//! dropped. HiGHS solves it exactly but pays a fixed cost per run far above the pivoting
//! itself, and the oracle runs it for every sequence it scores. Here the whole tableau is a
//! dense `rows x columns` array updated by exchange pivots.
//!
//! Why the dual simplex: every column is boxed or has a non-negative cost, so putting each
//! column at the bound its cost prefers is dual feasible at once, with no phase one; the row
//! logicals start basic. A row that stays violated with no column able to move it proves the
//! LP infeasible. Ties are the rule (the accelerations cost nothing, rows repeat), so after a
//! bounded number of pivots the choice switches to Bland's rule, which cannot cycle; a hard
//! pivot limit and a final check of every row against the original data turn any numerical
//! failure into an error, on which the caller falls back to HiGHS.

use thiserror::Error;

/// Feasibility tolerance on a basic variable's bounds (rows carry metres and m/s).
pub const PRIMAL_TOL: f64 = 1e-9;
/// Smallest tableau entry that may be pivoted on.
const PIVOT_TOL: f64 = 1e-9;
/// What the point may violate an original row or bound by after the pivots, absolute.
pub const CHECK_TOL: f64 = 1e-7;
/// Ratios this close count as tied.
const RATIO_TIE: f64 = 1e-12;

/// Why the dense simplex gave no verdict (the caller then asks HiGHS).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum SmallLpError {
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
    /// The most violated row leaves, the smallest dual ratio enters (the exact evaluation's
    /// rule: its LPs have a handful of columns).
    #[default]
    LargestViolation,
    /// Dual steepest edge (exact weights, read off the tableau) with the bound-flipping
    /// ratio test: boxed columns whose ratio comes first jump to their other bound instead
    /// of entering, as long as the leaving row stays violated. On the MILP's relaxation,
    /// whose columns are mostly `[0, 1]` boxes, that takes several times fewer pivots.
    SteepestEdge,
}

/// How a solve ended.
#[derive(Debug, Clone, PartialEq)]
pub enum LpOutcome {
    Optimal { x: Vec<f64>, objective: f64 },
    Infeasible,
}

/// `min offset + cost . x` subject to `row_lower <= A x <= row_upper`, `lower <= x <= upper`.
#[derive(Debug, Clone, Default)]
pub struct SmallLp {
    offset: f64,
    cost: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    row_lower: Vec<f64>,
    row_upper: Vec<f64>,
    row_start: Vec<usize>,
    terms: Vec<(usize, f64)>,
}

impl SmallLp {
    pub fn add_col(&mut self, cost: f64, lower: f64, upper: f64) -> usize {
        self.cost.push(cost);
        self.lower.push(lower);
        self.upper.push(upper);
        self.cost.len() - 1
    }

    /// Add `cost` to the objective coefficient of `col`.
    pub fn add_cost(&mut self, col: usize, cost: f64) {
        self.cost[col] += cost;
    }

    /// Add a constant to the objective.
    pub fn add_constant(&mut self, value: f64) {
        self.offset += value;
    }

    /// Add `lower <= sum(coef * col) <= upper`; repeated columns add up.
    pub fn add_row(&mut self, lower: f64, upper: f64, terms: &[(usize, f64)]) {
        self.row_start.push(self.terms.len());
        self.terms.extend_from_slice(terms);
        self.row_lower.push(lower);
        self.row_upper.push(upper);
    }

    pub fn num_cols(&self) -> usize {
        self.cost.len()
    }

    pub fn num_rows(&self) -> usize {
        self.row_lower.len()
    }

    pub fn cost(&self, col: usize) -> f64 {
        self.cost[col]
    }

    pub fn bounds(&self, col: usize) -> (f64, f64) {
        (self.lower[col], self.upper[col])
    }

    pub fn row_bounds(&self, row: usize) -> (f64, f64) {
        (self.row_lower[row], self.row_upper[row])
    }

    pub fn row_terms(&self, row: usize) -> &[(usize, f64)] {
        let end = self.row_start.get(row + 1).copied().unwrap_or(self.terms.len());
        &self.terms[self.row_start[row]..end]
    }

    pub fn objective_constant(&self) -> f64 {
        self.offset
    }

    /// `A x` of one row.
    pub fn activity(&self, row: usize, x: &[f64]) -> f64 {
        self.row_terms(row).iter().map(|&(c, a)| a * x[c]).sum()
    }

    /// The objective at `x`.
    pub fn objective(&self, x: &[f64]) -> f64 {
        self.offset + self.cost.iter().zip(x).map(|(c, x)| c * x).sum::<f64>()
    }

    /// Replace the box of `col`.
    pub fn set_bounds(&mut self, col: usize, lower: f64, upper: f64) {
        self.lower[col] = lower;
        self.upper[col] = upper;
    }

    /// Solve by the dual simplex; see the module documentation.
    pub fn solve(&self) -> Result<LpOutcome, SmallLpError> {
        self.solve_with(Pricing::LargestViolation)
    }

    /// Solve by the dual simplex with the given pivot rules.
    pub fn solve_with(&self, pricing: Pricing) -> Result<LpOutcome, SmallLpError> {
        let mut tableau = Tableau::new(self)?;
        let limit = 50 * (tableau.m + tableau.n) + 200;
        // Largest-violation pivoting is faster; Bland's rule past this point cannot cycle.
        let bland_after = 4 * (tableau.m + tableau.n) + 20;
        for iteration in 0..limit {
            let bland = iteration >= bland_after;
            let steepest = pricing == Pricing::SteepestEdge && !bland;
            tableau.update_basic_values(pricing);
            let leaving = if steepest {
                tableau.leaving_steepest()
            } else {
                tableau.leaving(bland)
            };
            let Some(p) = leaving else {
                return self.finish(&tableau);
            };
            let entering = if steepest {
                tableau.entering_flipping(p)
            } else {
                tableau.entering(p, bland)
            };
            let Some(q) = entering else {
                return Ok(LpOutcome::Infeasible);
            };
            tableau.pivot(p, q);
        }
        Err(SmallLpError::PivotLimit(limit))
    }

    /// Read the point off the final tableau and check it against the original data.
    fn finish(&self, t: &Tableau) -> Result<LpOutcome, SmallLpError> {
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
                return Err(SmallLpError::Inaccurate(Violated::Column(c)));
            }
        }
        for r in 0..self.num_rows() {
            let a = self.activity(r, &x);
            if !(a >= self.row_lower[r] - CHECK_TOL && a <= self.row_upper[r] + CHECK_TOL) {
                return Err(SmallLpError::Inaccurate(Violated::Row(r)));
            }
        }
        let objective = self.objective(&x);
        Ok(LpOutcome::Optimal { x, objective })
    }
}

/// The condensed tableau: basic variable `i` equals `sum_k t[i][k] * nonbasic_k`. Variables
/// `0..n` are the columns, `n..n + m` the row activities.
struct Tableau {
    n: usize,
    m: usize,
    /// `m x n`, row-major.
    t: Vec<f64>,
    /// Reduced cost of each nonbasic position.
    d: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    basic: Vec<usize>,
    nonbasic: Vec<usize>,
    /// Value of each nonbasic position (one of its bounds).
    value: Vec<f64>,
    at_upper: Vec<bool>,
    beta: Vec<f64>,
    /// 1.0 where a nonbasic position holds a row activity, else 0.0 (kept by `pivot`; the
    /// steepest-edge weights sum over these).
    logical_mask: Vec<f64>,
    /// The bound-flipping test's candidates and flips, kept to spare an allocation a pivot.
    candidates: Vec<(f64, usize)>,
    flips: Vec<usize>,
}

impl Tableau {
    fn new(lp: &SmallLp) -> Result<Self, SmallLpError> {
        let (n, m) = (lp.num_cols(), lp.num_rows());
        let mut t = vec![0.0; m * n];
        for r in 0..m {
            for &(c, a) in lp.row_terms(r) {
                t[r * n + c] += a;
            }
        }
        let (mut value, mut at_upper) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for c in 0..n {
            let (lo, hi, cost) = (lp.lower[c], lp.upper[c], lp.cost[c]);
            // The bound the cost prefers (either for a zero cost), so that every reduced cost
            // has the sign its bound needs.
            let up = cost < 0.0 || (cost == 0.0 && lo == f64::NEG_INFINITY);
            let v = if up { hi } else { lo };
            if !v.is_finite() {
                return Err(SmallLpError::NoDualStart(c));
            }
            value.push(v);
            at_upper.push(up);
        }
        Ok(Self {
            n,
            m,
            t,
            d: lp.cost.clone(),
            lower: lp.lower.iter().chain(&lp.row_lower).copied().collect(),
            upper: lp.upper.iter().chain(&lp.row_upper).copied().collect(),
            basic: (n..n + m).collect(),
            nonbasic: (0..n).collect(),
            value,
            at_upper,
            beta: vec![0.0; m],
            logical_mask: vec![0.0; n],
            candidates: Vec::new(),
            flips: Vec::new(),
        })
    }

    fn update_basic_values(&mut self, pricing: Pricing) {
        for (i, b) in self.beta.iter_mut().enumerate() {
            let row = &self.t[i * self.n..(i + 1) * self.n];
            *b = match pricing {
                // The evaluation's sums keep their order (its decisions stay bit for bit).
                Pricing::LargestViolation => row.iter().zip(&self.value).map(|(t, v)| t * v).sum(),
                Pricing::SteepestEdge => dot(row, &self.value),
            };
        }
    }

    fn violation(&self, i: usize) -> f64 {
        let v = self.basic[i];
        (self.lower[v] - self.beta[i]).max(self.beta[i] - self.upper[v])
    }

    /// The basic position to leave: the largest violation, or with `bland` the lowest
    /// variable index among the violated.
    fn leaving(&self, bland: bool) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for i in 0..self.m {
            let viol = self.violation(i);
            if viol <= PRIMAL_TOL {
                continue;
            }
            let better = match best {
                None => true,
                Some((b, _)) if bland => self.basic[i] < self.basic[b],
                Some((_, bv)) => viol > bv,
            };
            if better {
                best = Some((i, viol));
            }
        }
        best.map(|(i, _)| i)
    }

    /// The violated basic position with the largest `violation^2 / |e_p B^-1|^2`. Row `p`
    /// of `B^-1` is read off the tableau: its entries at the nonbasic row activities, and a
    /// 1 where `p` itself holds a row activity.
    fn leaving_steepest(&self) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for i in 0..self.m {
            let viol = self.violation(i);
            if viol <= PRIMAL_TOL {
                continue;
            }
            let row = &self.t[i * self.n..(i + 1) * self.n];
            let own = if self.basic[i] >= self.n { 1.0 } else { 0.0 };
            let weight = own + squares_where(row, &self.logical_mask);
            let score = viol * viol / weight.max(1e-12);
            if best.is_none_or(|(_, s)| score > s) {
                best = Some((i, score));
            }
        }
        best.map(|(i, _)| i)
    }

    /// The bound-flipping ratio test for leaving row `p`: candidates in order of their dual
    /// ratio; each boxed one whose full move leaves the row still violated flips to its
    /// other bound, and the first that would not is the entering position. `None` when
    /// every candidate flips and the row stays violated: the LP is infeasible.
    fn entering_flipping(&mut self, p: usize) -> Option<usize> {
        let n = self.n;
        let leaving = self.basic[p];
        let increase = self.beta[p] < self.lower[leaving];
        let mut gap = if increase {
            self.lower[leaving] - self.beta[p]
        } else {
            self.beta[p] - self.upper[leaving]
        };
        let mut candidates = std::mem::take(&mut self.candidates);
        let mut flips = std::mem::take(&mut self.flips);
        candidates.clear();
        flips.clear();
        let row = &self.t[p * n..(p + 1) * n];
        candidates.extend(
            row.iter()
                .enumerate()
                .filter_map(|(k, &a)| Some((self.dual_ratio(k, a, increase)?, k))),
        );
        // Equal ratios go to the larger pivot, then to the lower position.
        candidates.sort_by(|&(ra, ka), &(rb, kb)| {
            ra.total_cmp(&rb)
                .then(row[kb].abs().total_cmp(&row[ka].abs()))
                .then(ka.cmp(&kb))
        });
        let mut chosen = None;
        for &(_, k) in &candidates {
            let v = self.nonbasic[k];
            let reach = row[k].abs() * (self.upper[v] - self.lower[v]);
            if reach.is_finite() && gap - reach > PRIMAL_TOL {
                gap -= reach;
                flips.push(k);
            } else {
                chosen = Some(k);
                break;
            }
        }
        if chosen.is_some() {
            for &k in &flips {
                let v = self.nonbasic[k];
                self.at_upper[k] = !self.at_upper[k];
                self.value[k] = if self.at_upper[k] { self.upper[v] } else { self.lower[v] };
            }
        }
        self.candidates = candidates;
        self.flips = flips;
        chosen
    }

    /// The dual ratio of nonbasic position `k` (entry `a` of the leaving row), or `None` when
    /// it cannot move the row towards the bound it violates (`increase`: the lower one).
    fn dual_ratio(&self, k: usize, a: f64, increase: bool) -> Option<f64> {
        let v = self.nonbasic[k];
        if a.abs() <= PIVOT_TOL || self.lower[v] == self.upper[v] {
            return None;
        }
        // Direction the nonbasic must move for the row to move the right way.
        let up = increase == (a > 0.0);
        if up == self.at_upper[k] {
            return None;
        }
        // The reduced cost's sign is right up to rounding; clamp the rest to zero.
        let d = if self.at_upper[k] { -self.d[k] } else { self.d[k] };
        Some(d.max(0.0) / a.abs())
    }

    /// The nonbasic position that enters for leaving row `p` (the dual ratio test), or
    /// `None` when none can move the row towards its bound: the LP is infeasible.
    fn entering(&self, p: usize, bland: bool) -> Option<usize> {
        let increase = self.beta[p] < self.lower[self.basic[p]];
        let row = &self.t[p * self.n..(p + 1) * self.n];
        let mut best: Option<(usize, f64)> = None;
        for (k, &a) in row.iter().enumerate() {
            let Some(ratio) = self.dual_ratio(k, a, increase) else {
                continue;
            };
            let better = match best {
                None => true,
                Some((b, r)) => {
                    if ratio < r - RATIO_TIE {
                        true
                    } else if ratio > r + RATIO_TIE {
                        false
                    } else if bland {
                        self.nonbasic[k] < self.nonbasic[b]
                    } else {
                        a.abs() > row[b].abs()
                    }
                }
            };
            if better {
                best = Some((k, ratio));
            }
        }
        best.map(|(k, _)| k)
    }

    /// Exchange basic position `p` with nonbasic position `q`; the leaving variable rests
    /// at the bound it violated.
    fn pivot(&mut self, p: usize, q: usize) {
        let n = self.n;
        let leaving = self.basic[p];
        let increase = self.beta[p] < self.lower[leaving];
        let inv = 1.0 / self.t[p * n + q];
        {
            let row = &mut self.t[p * n..(p + 1) * n];
            for x in row.iter_mut() {
                *x *= -inv;
            }
            row[q] = inv;
        }
        let (before, rest) = self.t.split_at_mut(p * n);
        let (pivot_row, after) = rest.split_at_mut(n);
        for row in before.chunks_exact_mut(n).chain(after.chunks_exact_mut(n)) {
            eliminate(row, pivot_row, q, inv);
        }
        eliminate(&mut self.d, pivot_row, q, inv);
        self.basic[p] = self.nonbasic[q];
        self.nonbasic[q] = leaving;
        self.logical_mask[q] = f64::from(u8::from(leaving >= n));
        self.at_upper[q] = !increase;
        self.value[q] = if increase {
            self.lower[leaving]
        } else {
            self.upper[leaving]
        };
    }
}

/// `a . b` in four interleaved sums: a single running sum waits on each addition, and this
/// product is most of a pivot's work.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4.remainder().iter().zip(b4.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in a4.zip(b4) {
        for l in 0..4 {
            lanes[l] += x[l] * y[l];
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// `sum(row[k]^2 * mask[k])`, in four interleaved sums like [`dot`].
fn squares_where(row: &[f64], mask: &[f64]) -> f64 {
    let mut lanes = [0.0; 4];
    let (r4, m4) = (row.chunks_exact(4), mask.chunks_exact(4));
    let tail: f64 = r4.remainder().iter().zip(m4.remainder()).map(|(x, m)| x * x * m).sum();
    for (x, m) in r4.zip(m4) {
        for l in 0..4 {
            lanes[l] += x[l] * x[l] * m[l];
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// Substitute the pivot row (already solved for the entering variable) into `row`.
fn eliminate(row: &mut [f64], pivot_row: &[f64], q: usize, inv: f64) {
    let f = row[q];
    if f == 0.0 {
        return;
    }
    for (x, &a) in row.iter_mut().zip(pivot_row) {
        *x += f * a;
    }
    row[q] = f * inv;
}

#[cfg(test)]
pub(crate) mod tests;
