//! The LP of the best accelerations of one fixed sequence, written for HiGHS (the reference)
//! and for the dense simplex of `small_lp.rs` (the default).
//!
//! Both minimise the same objective over the same feasible set: per step the price of
//! `|v_des - v_h|` and of braking (beyond zero, `comfort_decel` and `firm_decel`), and per SV
//! and step the hysteresis and global slacks. The dense form is reduced first, exactly:
//! a price whose argument has one sign over the accelerations' box is linear there (or zero)
//! and goes into the objective, and a row the box already satisfies, or that repeats another
//! row's coefficients and slacks with a lower right-hand side, is dropped. What is left is
//! usually a handful of rows.

use super::{Mode, Requirement};
use crate::config::LpSolver;
use crate::highs_solver::{with_thread_lp, MipModel, MipStatus};
use crate::model::Rollout;
use crate::problem::Problem;
use crate::small_lp::{LpOutcome, SmallLp, SmallLpError};

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
            accel: u.iter().map(|&c| cols[c]).collect(),
            objective: result.objective,
        }),
        _ => None,
    }
}

/// The LP HiGHS gets, with the columns of the accelerations.
pub(crate) fn highs_model(problem: &Problem, r: &Rollout, rows: &[Requirement], mode: Mode) -> (MipModel, Vec<usize>) {
    let kin = &problem.kin;
    let w = &problem.weights;
    let (h_len, dt, v0) = (problem.horizon, kin.dt, problem.ego.v);
    let mut m = MipModel::default();
    let u: Vec<usize> = r
        .maneuvers
        .iter()
        .map(|mv| {
            let (lo, hi) = kin.bounds_of(mv.beta);
            m.add_col(0.0, lo, hi, false)
        })
        .collect();
    for h in 0..h_len {
        let mut speed: Vec<(usize, f64)> = u[..=h].iter().map(|&c| (c, dt)).collect();
        m.add_row(-v0, problem.speed_cap - v0, &mut speed.clone());
        let terminal = if h + 1 == h_len { w.w_speed_terminal } else { 0.0 };
        let dev = m.add_col(w.w_speed + terminal, 0.0, f64::INFINITY, false);
        speed.push((dev, 1.0));
        m.add_row(problem.desired_speed - v0, f64::INFINITY, &mut speed);
        let mut down: Vec<(usize, f64)> = u[..=h].iter().map(|&c| (c, -dt)).collect();
        down.push((dev, 1.0));
        m.add_row(v0 - problem.desired_speed, f64::INFINITY, &mut down);
        let brake = m.add_col(w.w_brake, 0.0, f64::INFINITY, false);
        m.add_row(0.0, f64::INFINITY, &mut [(brake, 1.0), (u[h], 1.0)]);
        let hard = m.add_col(w.w_hard_brake, 0.0, f64::INFINITY, false);
        m.add_row(problem.comfort_decel, f64::INFINITY, &mut [(hard, 1.0), (u[h], 1.0)]);
        let firm = m.add_col(w.w_firm_brake, 0.0, f64::INFINITY, false);
        m.add_row(problem.firm_decel, f64::INFINITY, &mut [(firm, 1.0), (u[h], 1.0)]);
    }
    let cells = problem.svs.len() * h_len;
    let (mut hys, mut glob) = (vec![None; cells], vec![None; cells]);
    for row in rows {
        let cell = row.sv * h_len + row.step;
        let c = &problem.svs[row.sv];
        let mut terms: Vec<(usize, f64)> = row.coef.iter().enumerate().map(|(j, &k)| (u[j], k)).collect();
        if row.band {
            let col = *hys[cell].get_or_insert_with(|| m.add_col(w.w_slack, 0.0, c.slack_bound(), false));
            terms.push((col, 1.0));
        }
        if mode == Mode::Relaxed {
            let col = *glob[cell].get_or_insert_with(|| m.add_col(w.w_global, 0.0, c.relax_bound, false));
            terms.push((col, 1.0));
        }
        m.add_row(row.rhs, f64::INFINITY, &mut terms);
    }
    (m, u)
}

/// A safety row kept for the dense LP.
struct Kept<'a> {
    coef: &'a [f64],
    hysteresis: Option<usize>,
    global: Option<usize>,
    rhs: f64,
}

/// The reduced LP solved by the dense simplex; `Err` when it gives no verdict.
pub fn by_dense(
    problem: &Problem,
    r: &Rollout,
    rows: &[Requirement],
    mode: Mode,
) -> Result<Option<Optimum>, SmallLpError> {
    let (lp, u) = dense_model(problem, r, rows, mode);
    Ok(match lp.solve()? {
        LpOutcome::Optimal { x, objective } => Some(Optimum {
            accel: u.iter().map(|&c| x[c]).collect(),
            objective,
        }),
        LpOutcome::Infeasible => None,
    })
}

/// The reduced LP the dense simplex gets, with the columns of the accelerations.
pub(crate) fn dense_model(problem: &Problem, r: &Rollout, rows: &[Requirement], mode: Mode) -> (SmallLp, Vec<usize>) {
    let kin = &problem.kin;
    let w = &problem.weights;
    let (h_len, dt, v0) = (problem.horizon, kin.dt, problem.ego.v);
    let boxes: Vec<(f64, f64)> = r.maneuvers.iter().map(|mv| kin.bounds_of(mv.beta)).collect();
    // Smallest and largest of `sum coef_j u_j` over the box.
    let range = |coef: &mut dyn Iterator<Item = (usize, f64)>| {
        coef.fold((0.0, 0.0), |(lo, hi), (j, a)| {
            let (a_lo, a_hi) = (a * boxes[j].0, a * boxes[j].1);
            (lo + a_lo.min(a_hi), hi + a_lo.max(a_hi))
        })
    };
    let mut lp = SmallLp::default();
    let u: Vec<usize> = boxes.iter().map(|&(lo, hi)| lp.add_col(0.0, lo, hi)).collect();
    // `weight * max(0, base + sum coef_j u_j)` over steps `first..=last` (one coefficient).
    let hinge = |lp: &mut SmallLp, weight: f64, base: f64, steps: std::ops::RangeInclusive<usize>, coef: f64| {
        if weight == 0.0 {
            return;
        }
        let (lo, hi) = range(&mut steps.clone().map(|j| (j, coef)));
        if base + hi <= 0.0 {
            return;
        }
        if base + lo >= 0.0 {
            lp.add_constant(weight * base);
            for j in steps {
                lp.add_cost(u[j], weight * coef);
            }
            return;
        }
        let t = lp.add_col(weight, 0.0, f64::INFINITY);
        let mut terms: Vec<(usize, f64)> = steps.map(|j| (u[j], -coef)).collect();
        terms.push((t, 1.0));
        lp.add_row(base, f64::INFINITY, &terms);
    };
    for h in 0..h_len {
        let terminal = if h + 1 == h_len { w.w_speed_terminal } else { 0.0 };
        let w_dev = w.w_speed + terminal;
        // |v_des - v_h| = max(0, v_h - v_des) + max(0, v_des - v_h), v_h = v0 + dt sum u.
        hinge(&mut lp, w_dev, v0 - problem.desired_speed, 0..=h, dt);
        hinge(&mut lp, w_dev, problem.desired_speed - v0, 0..=h, -dt);
        hinge(&mut lp, w.w_brake, 0.0, h..=h, -1.0);
        hinge(&mut lp, w.w_hard_brake, problem.comfort_decel, h..=h, -1.0);
        hinge(&mut lp, w.w_firm_brake, problem.firm_decel, h..=h, -1.0);
        let (lo, hi) = range(&mut (0..=h).map(|j| (j, dt)));
        if v0 + lo < 0.0 || v0 + hi > problem.speed_cap {
            let speed: Vec<(usize, f64)> = u[..=h].iter().map(|&c| (c, dt)).collect();
            lp.add_row(-v0, problem.speed_cap - v0, &speed);
        }
    }
    let cells = problem.svs.len() * h_len;
    let (mut hys, mut glob) = (vec![None; cells], vec![None; cells]);
    let mut kept: Vec<Kept> = Vec::new();
    for row in rows {
        let (lo, _) = range(&mut row.coef.iter().copied().enumerate());
        if lo >= row.rhs {
            continue;
        }
        let cell = row.sv * h_len + row.step;
        let c = &problem.svs[row.sv];
        let hysteresis = row
            .band
            .then(|| *hys[cell].get_or_insert_with(|| lp.add_col(w.w_slack, 0.0, c.slack_bound())));
        let global = (mode == Mode::Relaxed)
            .then(|| *glob[cell].get_or_insert_with(|| lp.add_col(w.w_global, 0.0, c.relax_bound)));
        let same = kept
            .iter_mut()
            .find(|k| k.coef == row.coef.as_slice() && k.hysteresis == hysteresis && k.global == global);
        match same {
            Some(k) => k.rhs = k.rhs.max(row.rhs),
            None => kept.push(Kept {
                coef: &row.coef,
                hysteresis,
                global,
                rhs: row.rhs,
            }),
        }
    }
    for k in &kept {
        let mut terms: Vec<(usize, f64)> = k.coef.iter().enumerate().map(|(j, &a)| (u[j], a)).collect();
        terms.extend(k.hysteresis.iter().chain(&k.global).map(|&col| (col, 1.0)));
        lp.add_row(k.rhs, f64::INFINITY, &terms);
    }
    (lp, u)
}

#[cfg(test)]
mod tests;
