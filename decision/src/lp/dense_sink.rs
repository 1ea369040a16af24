//! The sink for the dense simplex, with its exact reductions: a price whose argument keeps
//! one sign over the columns' boxes is linear there (or zero) and goes into the objective; a
//! speed limit or safety row the boxes already satisfy is dropped, and a safety row with the
//! same terms as another keeps only the larger right-hand side. What is left is usually a
//! handful of rows.

use std::cmp::Ordering;

use super::accel::{AccelSink, Price, Step};
use super::{Col, Expr, Sink};
use dense_lp::DenseLp;

/// Builds a [`DenseLp`].
#[derive(Debug, Default)]
pub struct DenseSink {
    lp: DenseLp,
    /// The safety rows kept so far, `terms >= demand`; written at [`DenseSink::finish`].
    safety: Vec<(Expr, f64)>,
    terms: Vec<(usize, f64)>,
}

impl DenseSink {
    fn bounds(&self) -> impl Fn(Col) -> (f64, f64) + '_ {
        |c| self.lp.bounds(c.0)
    }

    /// `price` as the objective takes it over the boxes: nothing where its argument is never
    /// positive, linear where it never is negative, else a column `t >= argument`.
    fn price(&mut self, price: Price<'_>) {
        if price.weight == 0.0 {
            return;
        }
        let (lo, hi) = price.terms.range(self.bounds());
        if price.base + hi <= 0.0 {
            return;
        }
        if price.base + lo >= 0.0 {
            self.lp.add_constant(price.weight * price.base);
            for (c, k) in price.terms.terms() {
                self.lp.add_cost(c.0, price.weight * k);
            }
            return;
        }
        let t = self.col(price.weight, 0.0, f64::INFINITY);
        let mut row = Expr::with_capacity(price.terms.cols.len() + 1);
        row -= price.terms;
        row += t;
        self.at_least(row, price.base);
    }

    /// The LP, the safety rows last.
    pub fn finish(mut self) -> DenseLp {
        for (row, demand) in std::mem::take(&mut self.safety) {
            self.at_least(row, demand);
        }
        self.lp
    }
}

impl Sink for DenseSink {
    fn col(&mut self, cost: f64, lower: f64, upper: f64) -> Col {
        Col(self.lp.add_col(cost, lower, upper))
    }

    fn add_row(&mut self, lower: f64, expr: Expr, upper: f64) {
        self.terms.clear();
        self.terms.extend(expr.terms.iter().map(|&(c, k)| (c.0, k)));
        self.lp
            .add_row(lower - expr.constant, upper - expr.constant, &self.terms);
    }
}

impl AccelSink for DenseSink {
    /// The prices (`v` above and below `v_des`, then braking), then the speed limit if the
    /// boxes let the speed leave `[0, v_cap]`.
    fn step(&mut self, step: Step<'_>) {
        let Step {
            limit,
            deviation,
            brakes,
            peak,
        } = step;
        for price in deviation.halves().into_iter().chain(brakes).chain(peak) {
            self.price(price);
        }
        let (lo, hi) = limit.change.range(self.bounds());
        if limit.may_bind(lo, hi) {
            self.row(limit.bounds(), Expr::from(limit.change));
        }
    }

    fn keeps(&self, gap: &Expr, demand: f64) -> bool {
        // Dropped when its smallest gap over the boxes meets the demand (a NaN keeps it).
        let (lo, _) = gap.range(self.bounds());
        !matches!(lo.partial_cmp(&demand), Some(Ordering::Greater | Ordering::Equal))
    }

    fn safety_row(&mut self, row: Expr, demand: f64) {
        match self.safety.iter_mut().find(|(kept, _)| kept.terms == row.terms) {
            Some((_, d)) => *d = d.max(demand),
            None => self.safety.push((row, demand)),
        }
    }
}
