//! Exact cost and feasibility of one ego action sequence. Once the sequence is fixed, every
//! slack has a closed-form optimal value, so this is the reference both backends answer to:
//! the enumeration backend minimises it directly, and the MILP's plan is re-scored by it.

use crate::model::{rollout, Rollout};
use crate::problem::Problem;
use crate::types::Action;

/// Which layer's constraints apply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Nominal MPC: hard rows strict, hysteresis slack within `d_HS`.
    Nominal,
    /// Layer A: every safety row may use a global slack up to `gamma * d_idm` at cost `w_q`.
    Relaxed,
}

/// A feasible sequence with its cost and optimal slacks.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    pub cost: f64,
    pub rollout: Rollout,
    /// Hysteresis slack per SV and step, `[sv * H + h]`.
    pub hysteresis_slack: Vec<f64>,
    /// Global slack per SV and step (zero in nominal mode).
    pub global_slack: Vec<f64>,
}

/// Largest shortfall `rhs - gap` over the SV's branches that share a lane with the ego at
/// step `h`; `None` when none does.
fn shortfall(
    problem: &Problem,
    sv: usize,
    h: usize,
    ego_x: f64,
    ego_occ: crate::lanes::LaneSet,
    rhs: f64,
) -> Option<f64> {
    let c = &problem.svs[sv];
    c.branches
        .iter()
        .filter(|b| b.occupancy[h].intersects(ego_occ))
        .map(|b| rhs - c.gap(b.x[h], ego_x, problem.length))
        .reduce(f64::max)
}

/// Behaviour and speed cost of a rollout (the part without slacks).
pub fn maneuver_cost(problem: &Problem, r: &Rollout) -> f64 {
    let w = &problem.weights;
    let mut cost = 0.0;
    for h in 0..r.actions.len() {
        cost += w.w_beta[(r.maneuvers[h].beta + 1) as usize];
        if r.actions[h].lateral != 0 {
            cost += w.w_lane_change;
        }
        cost += w.w_speed * (problem.desired_speed - r.v[h]).abs();
    }
    if let Some(last) = r.maneuvers.last() {
        cost += problem.lane_value[(last.lane - 1) as usize];
    }
    cost
}

/// Evaluate `actions`; `None` if `clip` discards an action or a constraint cannot be met.
pub fn evaluate(problem: &Problem, actions: &[Action], mode: Mode) -> Option<Evaluation> {
    let r = rollout(
        &problem.kin,
        problem.lanes,
        problem.start,
        problem.x0,
        problem.v0,
        problem.occupancy0,
        actions,
    )?;
    let tol = problem.tolerance;
    if r.v.iter().any(|&v| v < -tol || v > problem.speed_cap + tol) {
        return None;
    }
    let horizon = actions.len();
    let w = &problem.weights;
    let mut cost = maneuver_cost(problem, &r);
    let mut hysteresis_slack = vec![0.0; problem.svs.len() * horizon];
    let mut global_slack = vec![0.0; problem.svs.len() * horizon];
    for (i, c) in problem.svs.iter().enumerate() {
        for h in 0..horizon {
            let need_hard = shortfall(problem, i, h, r.x[h], r.occupancy[h], c.hard[h]);
            let Some(need_hard) = need_hard else {
                continue; // no shared lane at this step
            };
            // The band holds on the mean prediction, where its lanes meet the ego's.
            let need_hys = match c.corrective {
                Some(frozen) if c.mean_occupancy[h].intersects(r.occupancy[h]) => {
                    frozen.release_m - c.gap(c.mean_x[h], r.x[h], problem.length)
                }
                _ => f64::NEG_INFINITY,
            };
            let d_hs = c.slack_bound();
            let (slack_h, slack_g) = match mode {
                Mode::Nominal => {
                    if need_hard > tol || need_hys > d_hs + tol {
                        return None;
                    }
                    (need_hys.clamp(0.0, d_hs), 0.0)
                }
                Mode::Relaxed => {
                    // w_q > w_s: use the cheaper hysteresis slack first, the global slack only
                    // for what the hard row or the band cannot absorb.
                    let g = need_hard.max(need_hys - d_hs).max(0.0);
                    if g > c.relax_bound + tol {
                        return None;
                    }
                    let g = g.min(c.relax_bound);
                    ((need_hys - g).clamp(0.0, d_hs), g)
                }
            };
            hysteresis_slack[i * horizon + h] = slack_h;
            global_slack[i * horizon + h] = slack_g;
            cost += w.w_slack * slack_h + w.w_global * slack_g;
        }
    }
    Some(Evaluation {
        cost,
        rollout: r,
        hysteresis_slack,
        global_slack,
    })
}
