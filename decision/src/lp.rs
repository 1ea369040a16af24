//! The LP once: linear expressions over typed columns, the acceleration LP described one
//! time ([`accel`]), and the two sinks that lay a model out for its solver: [`HighsSink`]
//! (a [`MipModel`](crate::highs_solver::MipModel), for the MILP and the exact evaluation's
//! reference LP) and [`DenseSink`] (the dense simplex, with its exact reductions).
//!
//! Rows read as the formulation writes them (`b` a [`Sink`]):
//!
//! ```text
//! b.at_least(o - z, 0.0);                          // o[s][l] >= z[j][l]
//! b.at_most(left + right + down + up, 1.0);        // one action per step
//! b.at_least(t - price.terms, price.base);         // t >= base + terms
//! b.row(-v0..=cap - v0, Expr::from(change));       // 0 <= v0 + dt sum u <= v_cap
//! ```
//!
//! `col * k` is a [`Term`], `Scaled { cols, coef }` a borrowed `coef * sum(cols)`; both go
//! into an [`Expr`] by `+` and `-` without an allocation of their own. An expression keeps its
//! terms in the order they were written and its constant apart; a row's bounds are its bounds
//! minus the constant. The order matters: a column repeated in
//! a row is summed in it, and HiGHS and the dense simplex choose among tied optima by the
//! order of columns and rows, so the sinks emit exactly what the builders used to
//! (`milp::fingerprint_tests`).

use std::ops::{Add, AddAssign, Mul, Neg, RangeInclusive, Sub, SubAssign};

pub mod accel;
mod dense_sink;
mod highs_sink;

pub use dense_sink::DenseSink;
pub use highs_sink::{HighsSink, PriceCols};

/// A column of a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Col(usize);

impl Col {
    pub fn new(index: usize) -> Self {
        Self(index)
    }

    /// Its position among the model's columns (its entry in a solution).
    pub fn index(self) -> usize {
        self.0
    }
}

/// `sum coef * column + constant`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Expr {
    terms: Vec<(Col, f64)>,
    constant: f64,
}

impl Expr {
    pub fn constant(value: f64) -> Self {
        Self {
            terms: Vec::new(),
            constant: value,
        }
    }

    pub fn terms(&self) -> &[(Col, f64)] {
        &self.terms
    }

    pub fn constant_part(&self) -> f64 {
        self.constant
    }

    /// `(smallest, largest)` of the terms (without the constant) over column boxes, summed
    /// term by term in order.
    pub fn range(&self, bounds: impl Fn(Col) -> (f64, f64)) -> (f64, f64) {
        range(self.terms.iter().copied(), bounds)
    }

    /// An empty expression with room for `terms` terms.
    pub fn with_capacity(terms: usize) -> Self {
        Self {
            terms: Vec::with_capacity(terms),
            constant: 0.0,
        }
    }

    /// Empty it, keeping its buffer.
    pub fn clear(&mut self) {
        self.terms.clear();
        self.constant = 0.0;
    }

    /// Add terms, in order.
    pub fn extend(&mut self, terms: impl IntoIterator<Item = Term>) {
        for t in terms {
            *self += t;
        }
    }
}

/// `coef * col`: what `col * coef` gives, a term that an expression takes in without an
/// allocation of its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    pub col: Col,
    pub coef: f64,
}

/// `coef * (cols[0] + cols[1] + ...)`, borrowed: the acceleration LP's speeds and prices are
/// such sums over the accelerations so far, and a sink that reduces them needs no vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scaled<'a> {
    pub cols: &'a [Col],
    pub coef: f64,
}

impl Scaled<'_> {
    pub fn terms(&self) -> impl Iterator<Item = (Col, f64)> + '_ {
        self.cols.iter().map(|&c| (c, self.coef))
    }

    /// `(smallest, largest)` over column boxes, summed term by term in order (as
    /// [`Expr::range`]).
    pub fn range(&self, bounds: impl Fn(Col) -> (f64, f64)) -> (f64, f64) {
        range(self.terms(), bounds)
    }
}

impl Neg for Scaled<'_> {
    type Output = Self;
    fn neg(self) -> Self {
        Scaled {
            cols: self.cols,
            coef: -self.coef,
        }
    }
}

impl Linear for Scaled<'_> {
    fn add_to(self, e: &mut Expr, negate: bool) {
        let coef = signed(self.coef, negate);
        e.terms.extend(self.cols.iter().map(|&c| (c, coef)));
    }
}

impl From<Scaled<'_>> for Expr {
    fn from(s: Scaled<'_>) -> Self {
        Expr::default() + s
    }
}

/// `(smallest, largest)` of `sum k x_c` over the boxes `bounds(c)`, summed term by term.
fn range(terms: impl Iterator<Item = (Col, f64)>, bounds: impl Fn(Col) -> (f64, f64)) -> (f64, f64) {
    terms.fold((0.0, 0.0), |(lo, hi), (c, k)| {
        let (l, h) = bounds(c);
        let (a, b) = (k * l, k * h);
        (lo + a.min(b), hi + a.max(b))
    })
}

/// What an expression takes in by `+` and `-`: a column, a term, a constant, an expression.
/// Terms leave the constant as it is (not even `+ 0.0`, which would turn a `-0.0` into
/// `0.0`): a row's bounds are computed exactly as they were before the builder existed.
pub trait Linear {
    /// Add `self` (`negate`: `-self`) to `e`: its terms after `e`'s, its constant to `e`'s.
    fn add_to(self, e: &mut Expr, negate: bool);
}

/// `x` or `-x` (negation is exact).
fn signed(x: f64, negate: bool) -> f64 {
    if negate {
        -x
    } else {
        x
    }
}

impl Linear for Col {
    fn add_to(self, e: &mut Expr, negate: bool) {
        Term { col: self, coef: 1.0 }.add_to(e, negate);
    }
}

impl Linear for Term {
    fn add_to(self, e: &mut Expr, negate: bool) {
        e.terms.push((self.col, signed(self.coef, negate)));
    }
}

impl Linear for f64 {
    fn add_to(self, e: &mut Expr, negate: bool) {
        e.constant += signed(self, negate);
    }
}

impl Linear for Expr {
    fn add_to(self, e: &mut Expr, negate: bool) {
        (&self).add_to(e, negate);
    }
}

impl Linear for &Expr {
    fn add_to(self, e: &mut Expr, negate: bool) {
        e.terms.extend(self.terms.iter().map(|&(c, k)| (c, signed(k, negate))));
        e.constant += signed(self.constant, negate);
    }
}

impl From<Col> for Expr {
    fn from(c: Col) -> Self {
        Expr::default() + c
    }
}

impl From<Term> for Expr {
    fn from(t: Term) -> Self {
        Expr::default() + t
    }
}

impl From<f64> for Expr {
    fn from(value: f64) -> Self {
        Expr::constant(value)
    }
}

impl<T: Linear> AddAssign<T> for Expr {
    fn add_assign(&mut self, other: T) {
        other.add_to(self, false);
    }
}

impl<T: Linear> SubAssign<T> for Expr {
    fn sub_assign(&mut self, other: T) {
        other.add_to(self, true);
    }
}

impl<T: Linear> Add<T> for Expr {
    type Output = Expr;
    fn add(mut self, other: T) -> Expr {
        self += other;
        self
    }
}

impl<T: Linear> Sub<T> for Expr {
    type Output = Expr;
    fn sub(mut self, other: T) -> Expr {
        self -= other;
        self
    }
}

impl<T: Linear> Add<T> for Col {
    type Output = Expr;
    fn add(self, other: T) -> Expr {
        Expr::from(self) + other
    }
}

impl<T: Linear> Sub<T> for Col {
    type Output = Expr;
    fn sub(self, other: T) -> Expr {
        Expr::from(self) - other
    }
}

impl<T: Linear> Add<T> for Term {
    type Output = Expr;
    fn add(self, other: T) -> Expr {
        Expr::from(self) + other
    }
}

impl<T: Linear> Sub<T> for Term {
    type Output = Expr;
    fn sub(self, other: T) -> Expr {
        Expr::from(self) - other
    }
}

impl Neg for Expr {
    type Output = Expr;
    fn neg(mut self) -> Expr {
        for t in &mut self.terms {
            t.1 = -t.1;
        }
        self.constant = -self.constant;
        self
    }
}

impl Neg for Col {
    type Output = Term;
    fn neg(self) -> Term {
        Term { col: self, coef: -1.0 }
    }
}

impl Neg for Term {
    type Output = Term;
    fn neg(self) -> Term {
        Term {
            col: self.col,
            coef: -self.coef,
        }
    }
}

impl Mul<f64> for Expr {
    type Output = Expr;
    fn mul(mut self, k: f64) -> Expr {
        for t in &mut self.terms {
            t.1 *= k;
        }
        self.constant *= k;
        self
    }
}

impl Mul<Expr> for f64 {
    type Output = Expr;
    fn mul(self, e: Expr) -> Expr {
        e * self
    }
}

impl Mul<f64> for Col {
    type Output = Term;
    fn mul(self, coef: f64) -> Term {
        Term { col: self, coef }
    }
}

impl Mul<Col> for f64 {
    type Output = Term;
    fn mul(self, c: Col) -> Term {
        c * self
    }
}

/// A sum of columns, terms or expressions, in order (one allocation for a sized iterator of
/// terms).
impl<T: Linear> std::iter::Sum<T> for Expr {
    fn sum<I: Iterator<Item = T>>(iter: I) -> Expr {
        let mut e = Expr {
            terms: Vec::with_capacity(iter.size_hint().0),
            constant: 0.0,
        };
        for x in iter {
            e += x;
        }
        e
    }
}

/// Where a builder's columns and rows go.
pub trait Sink {
    /// A continuous column.
    fn col(&mut self, cost: f64, lower: f64, upper: f64) -> Col;

    /// `lower <= expr <= upper`, the constant moved to the bounds.
    fn add_row(&mut self, lower: f64, expr: Expr, upper: f64);

    /// `bounds.start() <= expr <= bounds.end()`.
    fn row(&mut self, bounds: RangeInclusive<f64>, expr: Expr) {
        let (lower, upper) = bounds.into_inner();
        self.add_row(lower, expr, upper);
    }

    /// `expr >= lower`.
    fn at_least(&mut self, expr: Expr, lower: f64) {
        self.add_row(lower, expr, f64::INFINITY);
    }

    /// `expr <= upper`.
    fn at_most(&mut self, expr: Expr, upper: f64) {
        self.add_row(f64::NEG_INFINITY, expr, upper);
    }

    /// `expr = value`.
    fn equal(&mut self, expr: Expr, value: f64) {
        self.add_row(value, expr, value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expressions_keep_their_terms_in_order_and_their_constant_apart() {
        let (x, y) = (Col::new(0), Col::new(1));
        let e = 2.0 * x + (y - 1.5) - (x * 0.5 + 3.0);
        assert_eq!(e.terms(), &[(x, 2.0), (y, 1.0), (x, -0.5)]);
        assert_eq!(e.constant_part(), -4.5);
        let s: Expr = [x, y, x].into_iter().sum();
        assert_eq!(s.terms(), &[(x, 1.0), (y, 1.0), (x, 1.0)]);
        assert_eq!((-s).terms()[1], (y, -1.0));
        let t: Expr = (0..3).map(|k| x * f64::from(k)).sum();
        assert_eq!(t.terms(), &[(x, 0.0), (x, 1.0), (x, 2.0)]);
        assert_eq!((y - -x).terms(), &[(y, 1.0), (x, 1.0)]);
        assert_eq!(e.range(|_| (-1.0, 2.0)), (-4.0, 6.5));
    }
}
