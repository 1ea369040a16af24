//! The decision problem as a MILP on HiGHS (paper III-E, III-F).
//!
//! Per step `s` (action `s`, state `s + 1`):
//! - action binaries `L-, L+, G-, G+` (lane left/right, beta down/up), at most one non-zero
//!   (or one per direction with combined actions);
//! - lane one-hot `z[s][l]` and beta one-hot `b[s][j]`, linked to the previous step by the
//!   actions — `clip` is implicit, since values outside the one-hots do not exist;
//! - position and speed are affine in the beta one-hots and are substituted, not columns;
//! - occupancy `o[s][l] >= z[j][l]` for `j <= s` (continuous): a lane stays occupied once
//!   targeted because a lane change outlasts the horizon;
//! - one safety row per SV, step and lane, for the tightest branch in that lane, switched
//!   on by `o` through a big-M taken from the ego's reachable positions (so it is exact and
//!   rows that can never bind are dropped, and lanes that can never be safe are fixed off);
//! - hysteresis rows with a slack in `[0, d_HS]` for SVs in corrective mode; in Layer A a
//!   global slack in `[0, gamma d_idm]` per SV and step on every safety row;
//! - `u[s] >= |v_des - v[s]|` for the speed term.

use crate::error::SolverError;
use crate::evaluate::{evaluate, Evaluation, Mode};
use crate::highs_solver::{HighsSolver, InterruptHandle, MipModel, MipStatus};
use crate::model::{admissible_sequences, rollout};
use crate::problem::Problem;
use crate::types::Action;

/// Column indices of one built model.
#[derive(Debug, Clone, Default)]
struct Layout {
    /// `[L-, L+, G-, G+]` per step.
    act: Vec<[usize; 4]>,
    /// Lane one-hot per step, index `l - 1`.
    lane: Vec<Vec<usize>>,
    /// Beta one-hot per step, index `beta + 1`.
    beta: Vec<[usize; 3]>,
    speed_dev: Vec<usize>,
    /// Occupancy column per step and lane, when some row needs it.
    occ: Vec<Vec<Option<usize>>>,
    /// Hysteresis and global slack per `[sv * H + s]`.
    hys: Vec<Option<usize>>,
    glob: Vec<Option<usize>>,
}

/// Outcome of one layer's solve.
#[derive(Debug, Clone)]
pub struct LayerOutcome {
    /// The plan, re-scored exactly; `None` when the layer is infeasible or gave no plan.
    pub evaluation: Option<Evaluation>,
    pub solver_objective: Option<f64>,
    pub rows: usize,
    pub columns: usize,
    pub binaries: usize,
    pub nodes: u64,
    pub warm_start: bool,
    /// The solve stopped at its time limit or an interrupt.
    pub stopped: bool,
}

/// The MILP backend: one long-lived HiGHS instance.
pub struct MilpBackend {
    solver: HighsSolver,
}

/// Reachable range of the ego's position at each step, over admissible, speed-feasible
/// sequences; gives exact big-M values.
fn reachable_positions(problem: &Problem) -> Vec<(f64, f64)> {
    let mut range = vec![(f64::INFINITY, f64::NEG_INFINITY); problem.horizon];
    for actions in admissible_sequences(problem.start, problem.lanes, problem.horizon, problem.combined_actions) {
        let Some(r) = rollout(
            &problem.kin,
            problem.lanes,
            problem.start,
            problem.x0,
            problem.v0,
            problem.occupancy0,
            &actions,
        ) else {
            continue;
        };
        let tol = problem.tolerance;
        if r.v.iter().any(|&v| v < -tol || v > problem.speed_cap + tol) {
            continue;
        }
        for (s, &x) in r.x.iter().enumerate() {
            range[s].0 = range[s].0.min(x);
            range[s].1 = range[s].1.max(x);
        }
    }
    range
}

/// Why a model could not be built: the layer is infeasible before any solve.
struct Infeasible;

// Steps index several parallel arrays (reach, branches, layout) at once.
#[allow(clippy::needless_range_loop)]
fn build(problem: &Problem, mode: Mode) -> Result<(MipModel, Layout), Infeasible> {
    let h_len = problem.horizon;
    let n = problem.lanes as usize;
    let w = &problem.weights;
    let kin = &problem.kin;
    let dt = kin.dt;
    let (a_dec, a_acc) = (kin.accel[0], kin.accel[2]);
    let mut m = MipModel::default();
    let mut lay = Layout::default();
    let mut terms: Vec<(usize, f64)> = Vec::with_capacity(64);

    for s in 0..h_len {
        let act = [
            m.add_col(w.w_lane_change, 0.0, 1.0, true),
            m.add_col(w.w_lane_change, 0.0, 1.0, true),
            m.add_col(0.0, 0.0, 1.0, true),
            m.add_col(0.0, 0.0, 1.0, true),
        ];
        // The terminal lane value is charged on the last step's lane.
        let lane: Vec<usize> = (0..n)
            .map(|l| {
                let cost = if s + 1 == h_len { problem.lane_value[l] } else { 0.0 };
                m.add_col(cost, 0.0, 1.0, true)
            })
            .collect();
        let beta = [
            m.add_col(w.w_beta[0], 0.0, 1.0, true),
            m.add_col(w.w_beta[1], 0.0, 1.0, true),
            m.add_col(w.w_beta[2], 0.0, 1.0, true),
        ];
        let dev = m.add_col(w.w_speed, 0.0, f64::INFINITY, false);

        if problem.combined_actions {
            terms.clear();
            terms.extend([(act[0], 1.0), (act[1], 1.0)]);
            m.add_row(f64::NEG_INFINITY, 1.0, &mut terms);
            terms.clear();
            terms.extend([(act[2], 1.0), (act[3], 1.0)]);
            m.add_row(f64::NEG_INFINITY, 1.0, &mut terms);
        } else {
            terms.clear();
            terms.extend(act.iter().map(|&c| (c, 1.0)));
            m.add_row(f64::NEG_INFINITY, 1.0, &mut terms);
        }
        // Lane one-hot and its link: sum l z[s][l] - sum l z[s-1][l] - L+ + L- = 0.
        terms.clear();
        terms.extend(lane.iter().map(|&c| (c, 1.0)));
        m.add_row(1.0, 1.0, &mut terms);
        terms.clear();
        terms.extend(lane.iter().enumerate().map(|(l, &c)| (c, (l + 1) as f64)));
        terms.extend([(act[1], -1.0), (act[0], 1.0)]);
        let rhs = if s == 0 {
            f64::from(problem.start.lane)
        } else {
            terms.extend(lay.lane[s - 1].iter().enumerate().map(|(l, &c)| (c, -((l + 1) as f64))));
            0.0
        };
        m.add_row(rhs, rhs, &mut terms);
        // Beta one-hot and its link.
        terms.clear();
        terms.extend(beta.iter().map(|&c| (c, 1.0)));
        m.add_row(1.0, 1.0, &mut terms);
        terms.clear();
        terms.extend([(beta[2], 1.0), (beta[0], -1.0), (act[3], -1.0), (act[2], 1.0)]);
        let rhs = if s == 0 {
            f64::from(problem.start.beta)
        } else {
            let prev = lay.beta[s - 1];
            terms.extend([(prev[2], -1.0), (prev[0], 1.0)]);
            0.0
        };
        m.add_row(rhs, rhs, &mut terms);

        lay.act.push(act);
        lay.lane.push(lane);
        lay.beta.push(beta);
        lay.speed_dev.push(dev);
    }

    // Speed: v[s] = v0 + dt * sum_{j<=s} a(b[j]); bounds and |v_des - v|.
    for s in 0..h_len {
        let speed_terms = |terms: &mut Vec<(usize, f64)>, sign: f64| {
            for j in 0..=s {
                terms.push((lay.beta[j][0], sign * dt * a_dec));
                terms.push((lay.beta[j][2], sign * dt * a_acc));
            }
        };
        terms.clear();
        speed_terms(&mut terms, 1.0);
        let steps = (s + 1) as f64;
        if problem.v0 + steps * dt * a_dec < 0.0 || problem.v0 + steps * dt * a_acc > problem.speed_cap {
            m.add_row(-problem.v0, problem.speed_cap - problem.v0, &mut terms);
        }
        terms.clear();
        speed_terms(&mut terms, 1.0);
        terms.push((lay.speed_dev[s], 1.0));
        m.add_row(problem.desired_speed - problem.v0, f64::INFINITY, &mut terms);
        terms.clear();
        speed_terms(&mut terms, -1.0);
        terms.push((lay.speed_dev[s], 1.0));
        m.add_row(problem.v0 - problem.desired_speed, f64::INFINITY, &mut terms);
    }

    // Safety rows.
    let reach = reachable_positions(problem);
    if reach.iter().any(|r| r.0 > r.1) {
        return Err(Infeasible); // no speed-feasible sequence at all
    }
    lay.occ = vec![vec![None; n]; h_len];
    lay.hys = vec![None; problem.svs.len() * h_len];
    lay.glob = vec![None; problem.svs.len() * h_len];
    let tol = problem.tolerance;
    for (i, c) in problem.svs.iter().enumerate() {
        let sign = if c.ahead { 1.0 } else { -1.0 };
        let d_hs = c.slack_bound();
        let glob_bound = if mode == Mode::Relaxed { c.relax_bound } else { 0.0 };
        for s in 0..h_len {
            let c_s = problem.x0 + (s + 1) as f64 * dt * problem.v0;
            let (x_lo, x_hi) = reach[s];
            for l in 1..=problem.lanes {
                // Hard rows: the tightest branch in this lane (the nearest SV position towards
                // the ego). The band row: the mean prediction, where its lanes include l.
                let tight = c
                    .branches
                    .iter()
                    .filter(|b| b.occupancy[s].contains(l))
                    .map(|b| b.x[s])
                    .reduce(if c.ahead { f64::min } else { f64::max });
                let mut rows: Vec<(f64, f64, bool)> = Vec::with_capacity(2);
                if let Some(x_b) = tight {
                    rows.push((x_b, c.hard[s], false));
                }
                if let Some(frozen) = c.corrective {
                    if c.mean_occupancy[s].contains(l) {
                        rows.push((c.mean_x[s], frozen.release_m, true));
                    }
                }
                for (x_b, rhs, hysteresis_row) in rows {
                    let violation = |x: f64| rhs + problem.length - sign * (x_b - x);
                    let (worst, best) = if c.ahead {
                        (violation(x_hi), violation(x_lo))
                    } else {
                        (violation(x_lo), violation(x_hi))
                    };
                    if worst <= 0.0 {
                        continue; // can never bind
                    }
                    let max_slack = glob_bound + if hysteresis_row { d_hs } else { 0.0 };
                    let unconditional = problem.occupancy0.contains(l);
                    if best > max_slack + tol {
                        if unconditional {
                            return Err(Infeasible);
                        }
                        // The ego can never be in lane l at this step: forbid it outright.
                        for j in 0..=s {
                            m.col_upper[lay.lane[j][(l - 1) as usize]] = 0.0;
                        }
                        continue;
                    }
                    terms.clear();
                    for j in 0..=s {
                        let k = dt * dt * ((s - j) as f64 + 0.5);
                        terms.push((lay.beta[j][0], -sign * k * a_dec));
                        terms.push((lay.beta[j][2], -sign * k * a_acc));
                    }
                    let idx = i * h_len + s;
                    if hysteresis_row {
                        let col = *lay.hys[idx].get_or_insert_with(|| m.add_col(w.w_slack, 0.0, d_hs, false));
                        terms.push((col, 1.0));
                    }
                    if mode == Mode::Relaxed {
                        let col =
                            *lay.glob[idx].get_or_insert_with(|| m.add_col(w.w_global, 0.0, c.relax_bound, false));
                        terms.push((col, 1.0));
                    }
                    let mut lower = rhs + problem.length - sign * (x_b - c_s);
                    if !unconditional {
                        let o = match lay.occ[s][(l - 1) as usize] {
                            Some(o) => o,
                            None => {
                                let o = m.add_col(0.0, 0.0, 1.0, false);
                                lay.occ[s][(l - 1) as usize] = Some(o);
                                o
                            }
                        };
                        terms.push((o, -worst));
                        lower -= worst;
                    }
                    m.add_row(lower, f64::INFINITY, &mut terms);
                }
            }
        }
    }
    // Occupancy links: o[s][l] >= z[j][l] for j <= s.
    for s in 0..h_len {
        for l in 0..n {
            if let Some(o) = lay.occ[s][l] {
                for j in 0..=s {
                    terms.clear();
                    terms.extend([(o, 1.0), (lay.lane[j][l], -1.0)]);
                    m.add_row(0.0, f64::INFINITY, &mut terms);
                }
            }
        }
    }
    Ok((m, lay))
}

/// Column vector of a sequence already evaluated feasible (to check the model against the
/// oracle).
#[cfg(test)]
fn columns_of(problem: &Problem, lay: &Layout, e: &Evaluation, num_cols: usize) -> Vec<f64> {
    let mut x = vec![0.0; num_cols];
    let r = &e.rollout;
    for s in 0..problem.horizon {
        let a = r.actions[s];
        let idx = match (a.lateral, a.longitudinal) {
            (-1, _) => Some(0),
            (1, _) => Some(1),
            _ => None,
        };
        if let Some(k) = idx {
            x[lay.act[s][k]] = 1.0;
        }
        match a.longitudinal {
            -1 => x[lay.act[s][2]] = 1.0,
            1 => x[lay.act[s][3]] = 1.0,
            _ => {}
        }
        x[lay.lane[s][(r.maneuvers[s].lane - 1) as usize]] = 1.0;
        x[lay.beta[s][(r.maneuvers[s].beta + 1) as usize]] = 1.0;
        x[lay.speed_dev[s]] = (problem.desired_speed - r.v[s]).abs();
        for (l, o) in lay.occ[s].iter().enumerate() {
            if let Some(o) = *o {
                x[o] = f64::from(u8::from(r.occupancy[s].contains((l + 1) as u8)));
            }
        }
    }
    for (idx, col) in lay.hys.iter().enumerate() {
        if let Some(col) = *col {
            x[col] = e.hysteresis_slack[idx];
        }
    }
    for (idx, col) in lay.glob.iter().enumerate() {
        if let Some(col) = *col {
            x[col] = e.global_slack[idx];
        }
    }
    x
}

fn decode(problem: &Problem, lay: &Layout, cols: &[f64]) -> Vec<Action> {
    (0..problem.horizon)
        .map(|s| {
            let on = |c: usize| cols[c] > 0.5;
            let act = lay.act[s];
            Action {
                lateral: if on(act[0]) {
                    -1
                } else if on(act[1]) {
                    1
                } else {
                    0
                },
                longitudinal: if on(act[2]) {
                    -1
                } else if on(act[3]) {
                    1
                } else {
                    0
                },
            }
        })
        .collect()
}

impl MilpBackend {
    pub fn new(time_limit_s: f64) -> Result<Self, SolverError> {
        Ok(Self {
            solver: HighsSolver::new(time_limit_s)?,
        })
    }

    pub fn interrupt_handle(&self) -> InterruptHandle {
        self.solver.interrupt_handle()
    }

    pub fn next_solve_id(&self) -> u64 {
        self.solver.next_solve_id()
    }

    pub fn set_time_limit(&mut self, seconds: f64) -> Result<(), SolverError> {
        self.solver.set_time_limit(seconds)
    }

    /// Solve one layer. `warm` are candidate sequences; the best feasible one is the
    /// incumbent whose cost cuts off the search.
    pub fn solve(&mut self, problem: &Problem, mode: Mode, warm: &[Vec<Action>]) -> Result<LayerOutcome, SolverError> {
        let Ok((model, lay)) = build(problem, mode) else {
            return Ok(LayerOutcome {
                evaluation: None,
                solver_objective: None,
                rows: 0,
                columns: 0,
                binaries: 0,
                nodes: 0,
                warm_start: false,
                stopped: false,
            });
        };
        // The best warm candidate bounds the search; if nothing beats it, it is the answer.
        let incumbent = warm
            .iter()
            .filter_map(|actions| evaluate(problem, actions, mode))
            .min_by(|a, b| a.cost.total_cmp(&b.cost));
        let cutoff = incumbent.as_ref().map(|e| e.cost + 1e-6 + 1e-9 * e.cost.abs());
        let result = self.solver.solve(&model, cutoff)?;
        let stopped = result.status == MipStatus::Stopped;
        let usable = matches!(result.status, MipStatus::Optimal | MipStatus::Stopped);
        let found = match (&result.columns, usable) {
            (Some(cols), true) => evaluate(problem, &decode(problem, &lay, cols), mode),
            _ => None,
        };
        let solver_objective = found.as_ref().map(|_| result.objective);
        let evaluation = match (found, incumbent) {
            (Some(f), Some(i)) => Some(if i.cost < f.cost { i } else { f }),
            (found, incumbent) => found.or(incumbent),
        };
        Ok(LayerOutcome {
            solver_objective,
            evaluation,
            rows: model.num_rows(),
            columns: model.num_cols(),
            binaries: model.num_integers(),
            nodes: result.nodes,
            warm_start: cutoff.is_some(),
            stopped,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::corpus::{paper_classes, SituationGenerator};
    use crate::model::admissible_sequences;
    use crate::problem::prepare;
    use crate::PlannerConfig;

    /// Every sequence the oracle finds feasible maps to a column vector that satisfies every
    /// row and bound of the MILP, with the same objective: the model cuts off nothing that
    /// is allowed and charges what the exact evaluation charges.
    #[test]
    fn oracle_feasible_sequences_are_milp_feasible_with_equal_cost() {
        let config = PlannerConfig::default();
        let mut checked = 0;
        for class in paper_classes() {
            let mut generator = SituationGenerator::new(99 + u64::from(class.id));
            for _ in 0..6 {
                let s = generator.situation(&config, &class);
                let problem = prepare(&config, &s).problem;
                for mode in [Mode::Nominal, Mode::Relaxed] {
                    let Ok((model, lay)) = build(&problem, mode) else {
                        let any = admissible_sequences(problem.start, problem.lanes, problem.horizon, false)
                            .iter()
                            .any(|a| evaluate(&problem, a, mode).is_some());
                        assert!(!any, "build declared infeasible, oracle disagrees: {s:?}");
                        continue;
                    };
                    for actions in admissible_sequences(problem.start, problem.lanes, problem.horizon, false) {
                        let Some(e) = evaluate(&problem, &actions, mode) else {
                            continue;
                        };
                        let x = columns_of(&problem, &lay, &e, model.num_cols());
                        for (c, &v) in x.iter().enumerate() {
                            assert!(
                                v >= model.col_lower[c] - 1e-7 && v <= model.col_upper[c] + 1e-7,
                                "column {c} = {v} outside [{}, {}] for {actions:?}; {s:?}",
                                model.col_lower[c],
                                model.col_upper[c]
                            );
                        }
                        for r in 0..model.num_rows() {
                            let (a, b) = (
                                model.row_start[r] as usize,
                                model
                                    .row_start
                                    .get(r + 1)
                                    .map_or(model.row_index.len(), |&e| e as usize),
                            );
                            let act: f64 = (a..b)
                                .map(|k| model.row_value[k] * x[model.row_index[k] as usize])
                                .sum();
                            assert!(
                                act >= model.row_lower[r] - 1e-6 && act <= model.row_upper[r] + 1e-6,
                                "row {r}: {act} outside [{}, {}] for {actions:?} in {mode:?}; {s:?}",
                                model.row_lower[r],
                                model.row_upper[r]
                            );
                        }
                        let objective: f64 = x.iter().zip(&model.col_cost).map(|(v, c)| v * c).sum();
                        assert!((objective - e.cost).abs() < 1e-6, "objective {objective} vs {}", e.cost);
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked}");
    }
}
