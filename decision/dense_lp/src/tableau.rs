//! The dense simplex's tableau and its pivot rules.

use crate::simplex::{DenseLp, Error, Pricing, PIVOT_TOL, PRIMAL_TOL, RATIO_TIE};

/// A reduced cost this close to zero may sit at either bound on a restart.
const DUAL_ZERO: f64 = 1e-9;

/// The condensed tableau: basic variable `i` equals `sum_k t[i][k] * nonbasic_k`. Variables
/// `0..n` are the columns, `n..n + m` the row activities. A solved tableau is also the start
/// of a re-solve with other bounds: its reduced costs do not depend on them.
#[derive(Clone)]
pub(crate) struct Tableau {
    n: usize,
    m: usize,
    /// `m x n`, row-major.
    t: Vec<f64>,
    /// Reduced cost of each nonbasic position.
    d: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    pub(crate) basic: Vec<usize>,
    pub(crate) nonbasic: Vec<usize>,
    /// Value of each nonbasic position (one of its bounds).
    pub(crate) value: Vec<f64>,
    at_upper: Vec<bool>,
    /// Value of each basic position: recomputed from the nonbasic values by
    /// `update_basic_values`, and carried along by each flip and pivot in between.
    pub(crate) beta: Vec<f64>,
    /// 1.0 where a nonbasic position holds a row activity, else 0.0 (kept by `pivot`; the
    /// steepest-edge weights sum over these).
    logical_mask: Vec<f64>,
    /// The bound-flipping test's candidates and flips, kept to spare an allocation a pivot.
    candidates: Vec<(f64, usize)>,
    flips: Vec<usize>,
}

impl Tableau {
    pub(crate) fn new(lp: &DenseLp) -> Result<Self, Error> {
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
                return Err(Error::NoDualStart(c));
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

    /// The dimensions, for the solve's pivot limits.
    pub(crate) fn size(&self) -> (usize, usize) {
        (self.m, self.n)
    }

    /// Make this solved tableau the start for `lp`, the same LP with other bounds: each
    /// nonbasic position moves to its bound on the side its reduced cost prefers. `false`
    /// when that bound is infinite (a fresh tableau must start instead).
    pub(crate) fn restart(&mut self, lp: &DenseLp) -> bool {
        if (lp.num_cols(), lp.num_rows()) != (self.n, self.m) {
            return false;
        }
        for (bound, new) in [
            (&mut self.lower, [&lp.lower, &lp.row_lower]),
            (&mut self.upper, [&lp.upper, &lp.row_upper]),
        ] {
            bound.clear();
            bound.extend(new[0].iter().chain(new[1]).copied());
        }
        for k in 0..self.n {
            let v = self.nonbasic[k];
            let (lo, hi, d) = (self.lower[v], self.upper[v], self.d[k]);
            // The side the reduced cost's sign asks for; at a zero one (to rounding) either
            // side is dual feasible, and staying where the parent had it moves the least.
            let up = if d > DUAL_ZERO {
                false
            } else if d < -DUAL_ZERO {
                true
            } else if self.at_upper[k] {
                hi.is_finite() || !lo.is_finite()
            } else {
                !lo.is_finite()
            };
            let value = if up { hi } else { lo };
            if !value.is_finite() {
                return false;
            }
            self.at_upper[k] = up;
            self.value[k] = value;
        }
        true
    }

    pub(crate) fn update_basic_values(&mut self, pricing: Pricing) {
        for (i, b) in self.beta.iter_mut().enumerate() {
            let row = &self.t[i * self.n..(i + 1) * self.n];
            *b = match pricing {
                // Summed in order: the largest-violation rule's results stay bit for bit.
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
    pub(crate) fn leaving(&self, bland: bool) -> Option<usize> {
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
    pub(crate) fn leaving_steepest(&self) -> Option<usize> {
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
    pub(crate) fn entering_flipping(&mut self, p: usize) -> Option<usize> {
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
                let old = self.value[k];
                self.value[k] = if self.at_upper[k] { self.upper[v] } else { self.lower[v] };
                self.move_basic_values(k, self.value[k] - old);
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
    pub(crate) fn entering(&self, p: usize, bland: bool) -> Option<usize> {
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
    pub(crate) fn pivot(&mut self, p: usize, q: usize) {
        let n = self.n;
        let leaving = self.basic[p];
        let increase = self.beta[p] < self.lower[leaving];
        let target = if increase {
            self.lower[leaving]
        } else {
            self.upper[leaving]
        };
        // The primal step: the entering position moves until the leaving row sits at the
        // bound it violated.
        let step = (target - self.beta[p]) / self.t[p * n + q];
        self.move_basic_values(q, step);
        let entering_value = self.value[q] + step;
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
        self.value[q] = target;
        self.beta[p] = entering_value;
    }

    /// Carry the basic values along a move of nonbasic position `k` by `delta`.
    fn move_basic_values(&mut self, k: usize, delta: f64) {
        if delta == 0.0 {
            return;
        }
        for (b, row) in self.beta.iter_mut().zip(self.t.chunks_exact(self.n)) {
            *b += row[k] * delta;
        }
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
