//! Exact cost and feasibility of one ego action sequence: the reference both backends answer
//! to. The enumeration backend minimises it directly, and the MILP's plan is re-scored by it.
//!
//! Once the sequence is fixed, the maneuver states, lanes and every row that applies are
//! known. With fixed accelerations (the discrete maps) every slack then has a closed-form
//! optimal value. With the continuous input `u`, what is left is a small LP over the
//! accelerations of the fixed sequence (at most `H` of them, bounded by their states); it is
//! written from the rollout's safety rows (independent of the MILP's encoding) and the
//! acceleration LP's one description, whose prices and slacks the MILP shares (`lp::accel`,
//! `accel_lp.rs`), and solved by the dense simplex, or by HiGHS as the reference. Its
//! accelerations are then scored by the closed form, so both paths share one definition of
//! the cost.

use crate::model::{rollout, Rollout};
use crate::problem::Problem;
use crate::types::Action;

pub mod accel_lp;

/// Which layer's constraints apply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Nominal MPC: hard rows strict, hysteresis slack within its bound.
    Nominal,
    /// Layer A: every safety row may use a global slack up to `gamma * d_idm` at cost `w_q`.
    Relaxed,
}

/// A feasible sequence with its cost and optimal slacks.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    pub cost: f64,
    /// The plan, at the accelerations chosen for it.
    pub rollout: Rollout,
    /// Hysteresis slack per SV and step, `[sv * H + h]`.
    pub hysteresis_slack: Vec<f64>,
    /// Global slack per SV and step (zero in nominal mode).
    pub global_slack: Vec<f64>,
}

/// One linear safety row on the accelerations: `sum_j coef[j] u_j (+ slacks) >= rhs`.
#[derive(Debug, Clone, PartialEq)]
pub struct Requirement {
    pub sv: usize,
    /// Step (0-based); `coef` has `step + 1` entries.
    pub step: usize,
    /// A hysteresis band row (its shortfall may be covered by the hysteresis slack).
    pub band: bool,
    pub rhs: f64,
    pub coef: Vec<f64>,
}

impl Requirement {
    fn shortfall(&self, u: &[f64]) -> f64 {
        self.rhs - self.coef.iter().zip(u).map(|(c, u)| c * u).sum::<f64>()
    }
}

/// Every safety row that applies to the sequence rolled out in `r`.
pub fn requirements(problem: &Problem, r: &Rollout) -> Vec<Requirement> {
    let kin = &problem.kin;
    let l = problem.length;
    let mut out = Vec::new();
    for (i, c) in problem.svs.iter().enumerate() {
        let sign = c.sign();
        let floor_matters = c.floor_matters();
        for h in 0..problem.horizon {
            let coast = kin.coasting_position(&problem.ego, h);
            let position: Vec<f64> = (0..=h).map(|j| -sign * kin.position_gain(h, j)).collect();
            let binding = c.binding_lanes(r.occupancy[h], problem.ego.occupancy);
            for (b, branch) in c.branches.iter().enumerate() {
                if !branch.occupancy[h].intersects(binding) {
                    continue;
                }
                let base = l - sign * (branch.x[h] - coast);
                out.push(Requirement {
                    sv: i,
                    step: h,
                    band: false,
                    rhs: c.margin[b][h] - c.allowance[h] + base,
                    coef: position.iter().map(|p| p - c.slope * kin.dt).collect(),
                });
                if floor_matters {
                    out.push(Requirement {
                        sv: i,
                        step: h,
                        band: false,
                        rhs: c.floor[h] - c.floor_allowance[h] + base,
                        coef: position.clone(),
                    });
                }
            }
            if let Some(frozen) = c.corrective {
                if c.mean_occupancy[h].intersects(r.occupancy[h]) {
                    // gap + tau s (v_sv - v_ego) >= d_rel, v_ego = v0 + dt sum(u).
                    let speed_gain = sign * c.anticipation_s * kin.dt;
                    out.push(Requirement {
                        sv: i,
                        step: h,
                        band: true,
                        rhs: frozen.release_m + l
                            - sign * (c.mean_x[h] - coast)
                            - c.band_anticipation(h, problem.ego.v),
                        coef: position.iter().map(|p| p - speed_gain).collect(),
                    });
                }
            }
        }
    }
    out
}

/// Behaviour, speed and comfort cost of a rollout (the part without slacks).
pub fn maneuver_cost(problem: &Problem, r: &Rollout) -> f64 {
    let w = &problem.weights;
    let mut cost = 0.0;
    for h in 0..r.actions.len() {
        cost += w.w_beta[(r.maneuvers[h].beta + 1) as usize];
        if r.actions[h].lateral != 0 {
            cost += w.w_lane_change;
        }
        if r.actions[h].longitudinal != 0 {
            cost += w.w_switch;
        }
        cost += w.w_speed * (problem.desired_speed - r.v[h]).abs();
        cost += w.w_brake * (-r.accel[h]).max(0.0);
        cost += w.w_hard_brake * (problem.comfort_decel - r.accel[h]).max(0.0);
        cost += w.w_firm_brake * (problem.firm_decel - r.accel[h]).max(0.0);
        cost += w.w_peak_brake * (problem.peak_decel - r.accel[h]).max(0.0);
    }
    if let (Some(last), Some(v)) = (r.maneuvers.last(), r.v.last()) {
        cost += problem.lane_value[(last.lane - 1) as usize];
        cost += w.w_beta_terminal[(last.beta + 1) as usize];
        cost += w.w_speed_terminal * (problem.desired_speed - v).abs();
    }
    cost
}

/// Cost and slacks of a rollout at its own accelerations; `None` if a row cannot be met.
fn score(problem: &Problem, r: Rollout, rows: &[Requirement], mode: Mode, tol: f64) -> Option<Evaluation> {
    if r.v.iter().any(|&v| v < -tol || v > problem.speed_cap + tol) {
        return None;
    }
    let horizon = problem.horizon;
    let cells = problem.svs.len() * horizon;
    let (mut need_hard, mut need_band) = (vec![f64::NEG_INFINITY; cells], vec![f64::NEG_INFINITY; cells]);
    for row in rows {
        let cell = row.sv * horizon + row.step;
        let need = if row.band { &mut need_band } else { &mut need_hard };
        need[cell] = need[cell].max(row.shortfall(&r.accel));
    }
    let w = &problem.weights;
    let mut cost = maneuver_cost(problem, &r);
    let mut hysteresis_slack = vec![0.0; cells];
    let mut global_slack = vec![0.0; cells];
    for cell in 0..cells {
        let (hard, band) = (need_hard[cell], need_band[cell]);
        if hard == f64::NEG_INFINITY && band == f64::NEG_INFINITY {
            continue;
        }
        let c = &problem.svs[cell / horizon];
        let d_hs = c.slack_bound();
        let (slack_h, slack_g) = match mode {
            Mode::Nominal => {
                if hard > tol || band > d_hs + tol {
                    return None;
                }
                (band.clamp(0.0, d_hs), 0.0)
            }
            Mode::Relaxed => {
                // w_q > w_s: use the cheaper hysteresis slack first, the global slack only for
                // what the hard rows or the band cannot absorb.
                let g = hard.max(band - d_hs).max(0.0);
                if g > c.relax_bound + tol {
                    return None;
                }
                let g = g.min(c.relax_bound);
                ((band - g).clamp(0.0, d_hs), g)
            }
        };
        hysteresis_slack[cell] = slack_h;
        global_slack[cell] = slack_g;
        cost += w.w_slack * slack_h + w.w_global * slack_g;
    }
    Some(Evaluation {
        cost,
        rollout: r,
        hysteresis_slack,
        global_slack,
    })
}

/// Evaluate `actions`; `None` if `clip` discards an action or a constraint cannot be met.
pub fn evaluate(problem: &Problem, actions: &[Action], mode: Mode) -> Option<Evaluation> {
    let r = rollout(&problem.kin, problem.lanes, &problem.ego, actions)?;
    let rows = requirements(problem, &r);
    if !problem.kin.is_continuous() {
        return score(problem, r, &rows, mode, problem.tolerance);
    }
    let accel = accel_lp::best(problem, &r, &rows, mode)?.accel;
    let r = r.with_accelerations(&problem.kin, &problem.ego, &accel);
    // The LP's point meets its rows within the solvers' feasibility tolerances (at most 1e-7
    // on rows that carry metres); score it with a little more room than that.
    score(problem, r, &rows, mode, problem.tolerance.max(1e-5))
}

/// Evaluate `actions` at given accelerations (one per step), as the MILP's plan comes back.
pub fn evaluate_at(problem: &Problem, actions: &[Action], accel: &[f64], mode: Mode) -> Option<Evaluation> {
    let r = rollout(&problem.kin, problem.lanes, &problem.ego, actions)?;
    let within = r.maneuvers.iter().zip(accel).all(|(m, &a)| {
        let (lo, hi) = problem.kin.bounds_of(m.beta);
        a >= lo - 1e-7 && a <= hi + 1e-7
    });
    if !within {
        return None;
    }
    let rows = requirements(problem, &r);
    let r = r.with_accelerations(&problem.kin, &problem.ego, accel);
    score(problem, r, &rows, mode, problem.tolerance.max(1e-5))
}
