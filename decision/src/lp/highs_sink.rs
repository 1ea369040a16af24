//! The sink for HiGHS: a [`MipModel`], every price a column with its rows, every row kept.

use super::accel::{AccelSink, Step};
use super::{Col, Expr, Sink};
use crate::highs_solver::MipModel;

/// Builds a [`MipModel`].
#[derive(Debug, Default)]
pub struct HighsSink {
    pub model: MipModel,
    /// Scratch terms of the row being added.
    terms: Vec<(usize, f64)>,
}

/// The price columns of one step: `|v - v_des|`, the three braking prices and the peak one.
#[derive(Debug, Clone, Copy)]
pub struct PriceCols {
    pub deviation: Col,
    pub brakes: [Col; 3],
    pub peak: Option<Col>,
}

impl HighsSink {
    /// A `{0, 1}` column.
    pub fn binary(&mut self, cost: f64) -> Col {
        Col(self.model.add_col(cost, 0.0, 1.0, true))
    }

    /// Lower `col`'s upper bound to `upper`.
    pub fn set_upper(&mut self, col: Col, upper: f64) {
        self.model.col_upper[col.0] = upper;
    }

    /// A step's price columns (the MILP makes them with its step's other columns, their rows
    /// later).
    pub fn price_columns(&mut self, step: &Step<'_>) -> PriceCols {
        PriceCols {
            deviation: self.col(step.deviation.weight, 0.0, f64::INFINITY),
            brakes: step.brakes.each_ref().map(|p| self.col(p.weight, 0.0, f64::INFINITY)),
            peak: step.peak.map(|p| self.col(p.weight, 0.0, f64::INFINITY)),
        }
    }

    /// A price column is at least its argument: `dev >= v_des - v`, `dev >= v - v_des`,
    /// `t >= base + terms` for each braking price.
    pub fn price_rows(&mut self, step: &Step<'_>, cols: &PriceCols) {
        let [over, under] = step.deviation.halves();
        for half in [under, over] {
            self.at_least(cols.deviation - half.terms, half.base);
        }
        let peak = step.peak.iter().zip(&cols.peak);
        for (price, &t) in step.brakes.iter().zip(&cols.brakes).chain(peak) {
            self.at_least(t - price.terms, price.base);
        }
    }

    pub fn into_model(self) -> MipModel {
        self.model
    }
}

impl Sink for HighsSink {
    fn col(&mut self, cost: f64, lower: f64, upper: f64) -> Col {
        Col(self.model.add_col(cost, lower, upper, false))
    }

    fn add_row(&mut self, lower: f64, expr: Expr, upper: f64) {
        self.terms.clear();
        self.terms.extend(expr.terms.iter().map(|&(c, k)| (c.0, k)));
        self.model
            .add_row(lower - expr.constant, upper - expr.constant, &mut self.terms);
    }
}

impl AccelSink for HighsSink {
    /// The speed limit row (always), then the price columns and their rows.
    fn step(&mut self, step: Step<'_>) {
        self.row(step.limit.bounds(), Expr::from(step.limit.change));
        let cols = self.price_columns(&step);
        self.price_rows(&step, &cols);
    }

    fn keeps(&self, _gap: &Expr, _demand: f64) -> bool {
        true
    }

    fn safety_row(&mut self, row: Expr, demand: f64) {
        self.at_least(row, demand);
    }
}
