//! The LP of the best accelerations of one fixed sequence, solved by HiGHS (the reference)
//! or by the dense simplex (the default).
//!
//! The LP is described once (`lp::accel::describe`: per step the price of `|v_des - v_h|`
//! and of braking beyond zero, `comfort_decel`, `firm_decel` and `peak_decel`, the speed
//! limit, and per SV and step the hysteresis and global slacks of the safety rows); the sinks
//! lay it out: HiGHS gets a column per acceleration, price and slack and every row
//! (`lp::HighsSink`), the dense simplex the exact reductions of `lp::DenseSink` (prices of
//! one sign over the boxes linear or gone, rows the boxes satisfy and repeated rows dropped),
//! usually a handful of rows.

use super::{Mode, Requirement};
use crate::config::LpSolver;
use crate::highs_solver::{with_thread_lp, MipModel, MipStatus};
use crate::lp::{accel, Col, DenseSink, HighsSink};
use crate::model::Rollout;
use crate::problem::Problem;
use dense_lp::{DenseLp, LpOutcome};

/// The accelerations of an optimum and the LP's objective there (without the sequence's
/// fixed prices).
#[derive(Debug, Clone, PartialEq)]
pub struct Optimum {
    pub accel: Vec<f64>,
    pub objective: f64,
}

/// Best accelerations by the configured solver; the dense simplex falls back to HiGHS when it
/// gives no verdict (a pivot limit or a final point off its rows).
pub fn best(problem: &Problem, r: &Rollout, rows: &[Requirement], mode: Mode) -> Option<Optimum> {
    match problem.evaluation_lp {
        LpSolver::Dense => by_dense(problem, r, rows, mode).unwrap_or_else(|_| by_highs(problem, r, rows, mode)),
        LpSolver::Highs => by_highs(problem, r, rows, mode),
    }
}

/// The LP as HiGHS gets it: one column per acceleration, price and slack, every row.
pub fn by_highs(problem: &Problem, r: &Rollout, rows: &[Requirement], mode: Mode) -> Option<Optimum> {
    let (m, u) = highs_model(problem, r, rows, mode);
    let result = with_thread_lp(|solver| solver.solve(&m, None)).expect("HiGHS LP of the exact evaluation");
    match (result.status, result.columns) {
        (MipStatus::Optimal, Some(cols)) => Some(Optimum {
            accel: u.iter().map(|c| cols[c.index()]).collect(),
            objective: result.objective,
        }),
        _ => None,
    }
}

/// The LP HiGHS gets, with the columns of the accelerations.
pub(crate) fn highs_model(problem: &Problem, r: &Rollout, rows: &[Requirement], mode: Mode) -> (MipModel, Vec<Col>) {
    let mut sink = HighsSink::default();
    let u = accel::describe(problem, r, rows, mode, &mut sink);
    (sink.into_model(), u)
}

/// The reduced LP solved by the dense simplex; `Err` when it gives no verdict.
pub fn by_dense(
    problem: &Problem,
    r: &Rollout,
    rows: &[Requirement],
    mode: Mode,
) -> Result<Option<Optimum>, dense_lp::Error> {
    let (lp, u) = dense_model(problem, r, rows, mode);
    Ok(match lp.solve()? {
        LpOutcome::Optimal { x, objective } => Some(Optimum {
            accel: u.iter().map(|c| x[c.index()]).collect(),
            objective,
        }),
        LpOutcome::Infeasible => None,
    })
}

/// The reduced LP the dense simplex gets, with the columns of the accelerations.
pub(crate) fn dense_model(problem: &Problem, r: &Rollout, rows: &[Requirement], mode: Mode) -> (DenseLp, Vec<Col>) {
    let mut sink = DenseSink::default();
    let u = accel::describe(problem, r, rows, mode, &mut sink);
    (sink.finish(), u)
}

#[cfg(test)]
mod tests;
