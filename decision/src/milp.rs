//! The decision problem as a MILP on HiGHS (paper III-E, III-F), built one constraint family
//! at a time so that each function sits beside its equations:
//!
//! - [`Builder::step_columns`]: per step `s` (action `s`, state `s + 1`) the action binaries
//!   `L-, L+, G-, G+`, the lane one-hot `z[s][l]`, the beta one-hot `b[s][j]`, the kinematic
//!   input `u[s]` and the auxiliaries of the speed and comfort terms;
//! - [`Builder::action_rows`]: at most one change per step (one per direction with combined
//!   actions);
//! - [`Builder::transition_rows`]: one-hots linked to the previous step by transition flows
//!   whose up / down parts are the actions (a network flow: its LP relaxation is tight), so
//!   `clip` is implicit (values outside the one-hots do not exist);
//! - [`Builder::lane_change_rows`]: a plan targets at most one lane the ego does not occupy
//!   now, and none while a lane change is under way (`model::new_lanes_allowed`);
//! - [`Builder::input_rows`]: `u[s]` inside the range of the state it is in;
//! - [`Builder::speed_rows`]: `0 <= v[s] <= v_cap`, `dev[s] >= |v_des - v[s]|`, and the braking
//!   auxiliaries; position and speed are affine in `u` and substituted, not columns;
//! - [`Builder::safety_rows`]: per SV, step and lane the tightest branch's rows, switched on
//!   by the occupancy `o[s][l]` with a big-M from the bounds of `u` (rows that can never bind
//!   are dropped, lanes that can never be safe are fixed off), the hysteresis band with its
//!   slack, and Layer A's global slack;
//! - [`Builder::occupancy_rows`]: `o[s][l] >= z[j][l]` for `j <= s`: a lane stays occupied
//!   once targeted because a lane change outlasts the horizon.
//!
//! [`MilpBackend`] solves a layer's LP relaxation first and runs the MIP only when the
//! relaxation does not settle it (`backend.rs`).

use crate::evaluate::Mode;
use crate::highs_solver::MipModel;
use crate::problem::{Problem, SvConstraint};
use crate::types::Action;

/// A linear expression over the model's columns plus a constant.
#[derive(Debug, Clone, Default)]
struct Expr {
    terms: Vec<(usize, f64)>,
    constant: f64,
}

impl Expr {
    fn term(mut self, col: usize, coef: f64) -> Self {
        self.terms.push((col, coef));
        self
    }

    fn sum(cols: impl IntoIterator<Item = usize>) -> Self {
        Expr {
            terms: cols.into_iter().map(|c| (c, 1.0)).collect(),
            constant: 0.0,
        }
    }

    fn plus(mut self, other: &Expr) -> Self {
        self.terms.extend_from_slice(&other.terms);
        self.constant += other.constant;
        self
    }

    fn scaled(&self, k: f64) -> Self {
        Expr {
            terms: self.terms.iter().map(|&(c, v)| (c, k * v)).collect(),
            constant: k * self.constant,
        }
    }
}

/// An entry of a one-hot: a column, or a value known before the solve.
#[derive(Debug, Clone, Copy)]
enum OneHot {
    Column(usize),
    Fixed(bool),
}

/// Which one-hot chain a transition flow belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Chain {
    Lane,
    Beta,
}

/// A transition flow column: one-hot entry `from` at step `step - 1` to `to` at `step`
/// (indices into the lane or beta one-hot).
#[derive(Debug, Clone, Copy)]
#[cfg_attr(not(test), allow(dead_code))] // read by the tests that map plans to columns
struct Flow {
    chain: Chain,
    step: usize,
    from: usize,
    to: usize,
    col: usize,
}

/// Column indices of one built model.
#[derive(Debug, Clone, Default)]
struct Columns {
    /// `[L-, L+, G-, G+]` per step.
    act: Vec<[usize; 4]>,
    /// Lane one-hot per step, index `l - 1`.
    lane: Vec<Vec<usize>>,
    /// Beta one-hot per step, index `beta + 1`.
    beta: Vec<[usize; 3]>,
    /// Transition flows of both chains.
    flows: Vec<Flow>,
    /// Kinematic input per step.
    accel: Vec<usize>,
    speed_dev: Vec<usize>,
    brake: Vec<usize>,
    hard_brake: Vec<usize>,
    firm_brake: Vec<usize>,
    /// Occupancy column per step and lane, when some row needs it.
    occ: Vec<Vec<Option<usize>>>,
    /// `(lane index, column)`: whether the plan visits a lane the ego does not occupy now.
    seen: Vec<(usize, usize)>,
    /// Hysteresis and global slack per `[sv * H + s]`.
    hys: Vec<Option<usize>>,
    glob: Vec<Option<usize>>,
}

/// The layer is infeasible before any solve.
struct Infeasible;

/// Builds the model of one layer.
struct Builder<'p> {
    problem: &'p Problem,
    mode: Mode,
    m: MipModel,
    cols: Columns,
}

impl<'p> Builder<'p> {
    fn new(problem: &'p Problem, mode: Mode) -> Self {
        Self {
            problem,
            mode,
            m: MipModel::default(),
            cols: Columns::default(),
        }
    }

    fn row(&mut self, lower: f64, expr: Expr, upper: f64) {
        let mut terms = expr.terms;
        self.m.add_row(lower - expr.constant, upper - expr.constant, &mut terms);
    }

    fn at_least(&mut self, expr: Expr, lower: f64) {
        self.row(lower, expr, f64::INFINITY);
    }

    fn equal(&mut self, expr: Expr, value: f64) {
        self.row(value, expr, value);
    }

    /// `v[s] - v0 = dt sum_{j <= s} u[j]`.
    fn speed_change(&self, s: usize) -> Expr {
        let dt = self.problem.kin.dt;
        Expr {
            terms: self.cols.accel[..=s].iter().map(|&c| (c, dt)).collect(),
            constant: 0.0,
        }
    }

    /// Ego position after step `s`.
    fn position(&self, s: usize) -> Expr {
        let kin = &self.problem.kin;
        Expr {
            terms: (0..=s).map(|j| (self.cols.accel[j], kin.position_gain(s, j))).collect(),
            constant: kin.coasting_position(&self.problem.ego, s),
        }
    }

    fn step_columns(&mut self) {
        let p = self.problem;
        let w = &p.weights;
        let (u_min, u_max) = p.kin.extreme_accels();
        for s in 0..p.horizon {
            let act = [
                self.m.add_col(w.w_lane_change, 0.0, 1.0, true),
                self.m.add_col(w.w_lane_change, 0.0, 1.0, true),
                self.m.add_col(w.w_switch, 0.0, 1.0, true),
                self.m.add_col(w.w_switch, 0.0, 1.0, true),
            ];
            // The terminal lane value is charged on the last step's lane.
            let lane = (0..p.lanes as usize)
                .map(|l| {
                    let cost = if s + 1 == p.horizon { p.lane_value[l] } else { 0.0 };
                    self.m.add_col(cost, 0.0, 1.0, true)
                })
                .collect();
            // The terminal state price is charged on the last step's state.
            let last = s + 1 == p.horizon;
            let beta = std::array::from_fn::<_, 3, _>(|b| {
                let terminal = if last { w.w_beta_terminal[b] } else { 0.0 };
                self.m.add_col(w.w_beta[b] + terminal, 0.0, 1.0, true)
            });
            self.cols.act.push(act);
            self.cols.lane.push(lane);
            self.cols.beta.push(beta);
            self.cols.accel.push(self.m.add_col(0.0, u_min, u_max, false));
            // The terminal speed weight is charged on the last step's deviation.
            let terminal = if s + 1 == p.horizon { w.w_speed_terminal } else { 0.0 };
            let dev = self.m.add_col(w.w_speed + terminal, 0.0, f64::INFINITY, false);
            self.cols.speed_dev.push(dev);
            self.cols
                .brake
                .push(self.m.add_col(w.w_brake, 0.0, f64::INFINITY, false));
            self.cols
                .hard_brake
                .push(self.m.add_col(w.w_hard_brake, 0.0, f64::INFINITY, false));
            self.cols
                .firm_brake
                .push(self.m.add_col(w.w_firm_brake, 0.0, f64::INFINITY, false));
        }
    }

    fn action_rows(&mut self) {
        for s in 0..self.problem.horizon {
            let act = self.cols.act[s];
            if self.problem.combined_actions {
                self.row(f64::NEG_INFINITY, Expr::sum([act[0], act[1]]), 1.0);
                self.row(f64::NEG_INFINITY, Expr::sum([act[2], act[3]]), 1.0);
            } else {
                self.row(f64::NEG_INFINITY, Expr::sum(act), 1.0);
            }
        }
    }

    /// The lane and beta one-hots follow their previous step through transition flows
    /// `x[s][i -> j]` (`|i - j| <= 1`): `sum_j x[i -> j]` is the previous one-hot's `i`,
    /// `sum_i x[i -> j]` this step's `j`, and the up / down flows are the actions `L+`, `L-`
    /// (`G+`, `G-`). A one-hot chain written this way is a network flow, whose LP relaxation
    /// is integral; the shorter link `sum_j j z[s][j] = sum_j j z[s-1][j] + L+ - L-` lets the
    /// relaxation reach a lane (or a beta) it could not by mixing its neighbours at no action
    /// cost, and left most MIPs to branching.
    fn transition_rows(&mut self) {
        let p = self.problem;
        for s in 0..p.horizon {
            let act = self.cols.act[s];
            let (lane_now, lane_prev) = (self.cols.lane[s].clone(), self.previous_one_hot(s, true));
            self.flow_rows(Chain::Lane, s, &lane_prev, &lane_now, act[0], act[1]);
            let (beta_now, beta_prev) = (self.cols.beta[s].to_vec(), self.previous_one_hot(s, false));
            self.flow_rows(Chain::Beta, s, &beta_prev, &beta_now, act[2], act[3]);
        }
    }

    /// The previous step's lane (or beta) one-hot: columns, or the ego's state at `s = 0`.
    fn previous_one_hot(&self, s: usize, lane: bool) -> Vec<OneHot> {
        let p = self.problem;
        match (s, lane) {
            (0, true) => (1..=p.lanes).map(|l| OneHot::Fixed(l == p.ego.maneuver.lane)).collect(),
            (0, false) => (-1..=1).map(|b| OneHot::Fixed(b == p.ego.maneuver.beta)).collect(),
            (_, true) => self.cols.lane[s - 1].iter().map(|&c| OneHot::Column(c)).collect(),
            (_, false) => self.cols.beta[s - 1].iter().map(|&c| OneHot::Column(c)).collect(),
        }
    }

    /// Flow rows from `prev` to `now` with the down / up flows equal to the action columns.
    fn flow_rows(&mut self, chain: Chain, step: usize, prev: &[OneHot], now: &[usize], down: usize, up: usize) {
        let n = now.len();
        let mut into: Vec<Expr> = now.iter().map(|&c| Expr::default().term(c, -1.0)).collect();
        let (mut down_flow, mut up_flow) = (Expr::default().term(down, -1.0), Expr::default().term(up, -1.0));
        for (i, from) in prev.iter().enumerate() {
            if matches!(from, OneHot::Fixed(false)) {
                continue; // no flow leaves a state the ego is not in
            }
            let mut out = Expr::default();
            let reachable = i.saturating_sub(1)..(i + 2).min(n);
            for (j, target) in into.iter_mut().enumerate().take(reachable.end).skip(reachable.start) {
                let x = self.m.add_col(0.0, 0.0, 1.0, false);
                self.cols.flows.push(Flow {
                    chain,
                    step,
                    from: i,
                    to: j,
                    col: x,
                });
                out = out.term(x, 1.0);
                *target = std::mem::take(target).term(x, 1.0);
                if j < i {
                    down_flow = down_flow.term(x, 1.0);
                } else if j > i {
                    up_flow = up_flow.term(x, 1.0);
                }
            }
            match *from {
                OneHot::Column(c) => self.equal(out.term(c, -1.0), 0.0),
                _ => self.equal(out, 1.0),
            }
        }
        for row in into {
            self.equal(row, 0.0);
        }
        self.equal(down_flow, 0.0);
        self.equal(up_flow, 0.0);
    }

    /// `sum_j lo(j) b[s][j] <= u[s] <= sum_j hi(j) b[s][j]`.
    /// At most `new_lanes_allowed` lanes outside the ones the ego occupies now are visited:
    /// `seen[l] >= z[s][l]` for every step, `sum_l seen[l] <= allowed` (none: the one-hots of
    /// those lanes are fixed off).
    fn lane_change_rows(&mut self) {
        let p = self.problem;
        let allowed = crate::model::new_lanes_allowed(p.ego.occupancy);
        let new_lanes: Vec<usize> = (1..=p.lanes)
            .filter(|&l| !p.ego.occupancy.contains(l))
            .map(|l| (l - 1) as usize)
            .collect();
        if allowed == 0 {
            for s in 0..p.horizon {
                for &l in &new_lanes {
                    self.m.col_upper[self.cols.lane[s][l]] = 0.0;
                }
            }
            return;
        }
        let mut seen_any = Expr::default();
        for &l in &new_lanes {
            let seen = self.m.add_col(0.0, 0.0, 1.0, false);
            self.cols.seen.push((l, seen));
            for s in 0..p.horizon {
                self.at_least(Expr::default().term(seen, 1.0).term(self.cols.lane[s][l], -1.0), 0.0);
            }
            seen_any = seen_any.term(seen, 1.0);
        }
        self.row(f64::NEG_INFINITY, seen_any, allowed as f64);
    }

    fn input_rows(&mut self) {
        let kin = self.problem.kin;
        for s in 0..self.problem.horizon {
            let (u, beta) = (self.cols.accel[s], self.cols.beta[s]);
            let mut lower = Expr::default().term(u, 1.0);
            let mut upper = Expr::default().term(u, 1.0);
            for (j, &b) in beta.iter().enumerate() {
                let (lo, hi) = kin.bounds[j];
                lower = lower.term(b, -lo);
                upper = upper.term(b, -hi);
            }
            self.at_least(lower, 0.0);
            self.row(f64::NEG_INFINITY, upper, 0.0);
        }
    }

    fn speed_rows(&mut self) {
        let p = self.problem;
        let (u_min, u_max) = p.kin.extreme_accels();
        for s in 0..p.horizon {
            let dv = self.speed_change(s);
            let steps = (s + 1) as f64 * p.kin.dt;
            if p.ego.v + steps * u_min < 0.0 || p.ego.v + steps * u_max > p.speed_cap {
                self.row(-p.ego.v, dv.clone(), p.speed_cap - p.ego.v);
            }
            let dev = self.cols.speed_dev[s];
            self.at_least(dv.clone().term(dev, 1.0), p.desired_speed - p.ego.v);
            self.at_least(dv.scaled(-1.0).term(dev, 1.0), p.ego.v - p.desired_speed);
            let u = self.cols.accel[s];
            self.at_least(Expr::default().term(self.cols.brake[s], 1.0).term(u, 1.0), 0.0);
            self.at_least(
                Expr::default().term(self.cols.hard_brake[s], 1.0).term(u, 1.0),
                p.comfort_decel,
            );
            self.at_least(
                Expr::default().term(self.cols.firm_brake[s], 1.0).term(u, 1.0),
                p.firm_decel,
            );
        }
    }

    /// Range of `expr`'s column part over the box of `u` (the only columns a safety row's
    /// gap depends on).
    fn accel_range(&self, expr: &Expr) -> (f64, f64) {
        let (u_min, u_max) = self.problem.kin.extreme_accels();
        expr.terms.iter().fold((0.0, 0.0), |(lo, hi), &(_, k)| {
            let (a, b) = (k * u_min, k * u_max);
            (lo + a.min(b), hi + a.max(b))
        })
    }

    fn occupancy(&mut self, s: usize, l: usize) -> usize {
        match self.cols.occ[s][l] {
            Some(o) => o,
            None => {
                let o = self.m.add_col(0.0, 0.0, 1.0, false);
                self.cols.occ[s][l] = Some(o);
                o
            }
        }
    }

    /// Rows of one SV in lane `l` at step `s`: `(gap expression, demand, is band row)`, the
    /// gap expression being the signed gap to the tightest branch without the demand.
    fn lane_rows(&self, c: &SvConstraint, s: usize, l: u8) -> Vec<(Expr, f64, bool)> {
        let p = self.problem;
        let sign = c.sign();
        let ego_gap = self.position(s).scaled(-sign);
        let mut rows = Vec::with_capacity(3);
        let binding = c.binding_lanes(crate::lanes::LaneSet::single(l), p.ego.occupancy);
        if !binding.is_empty() {
            let in_lane: Vec<usize> = (0..c.branches.len())
                .filter(|&b| c.branches[b].occupancy[s].contains(l))
                .collect();
            // The tightest branch: the largest demand net of its position.
            let net = |b: usize, demand: f64| demand - sign * c.branches[b].x[s];
            let tightest = |demand: &dyn Fn(usize) -> f64| in_lane.iter().map(|&b| net(b, demand(b))).reduce(f64::max);
            let slope = self.speed_change(s).scaled(-c.slope);
            if let Some(d) = tightest(&|b| c.margin[b][s]) {
                rows.push((ego_gap.clone().plus(&slope), d - c.allowance[s] + p.length, false));
            }
            if c.floor_matters() {
                if let Some(d) = tightest(&|_| c.floor[s]) {
                    rows.push((ego_gap.clone(), d - c.floor_allowance[s] + p.length, false));
                }
            }
        }
        if let Some(frozen) = c.corrective {
            if c.mean_occupancy[s].contains(l) {
                // gap + tau s (v_sv - v_ego) >= d_rel.
                let anticipated = ego_gap.plus(&self.speed_change(s).scaled(-sign * c.anticipation_s));
                let demand = frozen.release_m - sign * c.mean_x[s] + p.length - c.band_anticipation(s, p.ego.v);
                rows.push((anticipated, demand, true));
            }
        }
        rows
    }

    fn safety_rows(&mut self) -> Result<(), Infeasible> {
        let p = self.problem;
        let w = &p.weights;
        let (h_len, n) = (p.horizon, p.lanes as usize);
        self.cols.occ = vec![vec![None; n]; h_len];
        self.cols.hys = vec![None; p.svs.len() * h_len];
        self.cols.glob = vec![None; p.svs.len() * h_len];
        let tol = p.tolerance;
        for (i, c) in p.svs.iter().enumerate() {
            let glob_bound = if self.mode == Mode::Relaxed { c.relax_bound } else { 0.0 };
            for s in 0..h_len {
                for l in 1..=p.lanes {
                    for (gap, demand, band) in self.lane_rows(c, s, l) {
                        // Row: gap + slacks >= demand. Its violation `demand - gap` ranges
                        // over [best, worst] as u ranges over its box.
                        let (lo, hi) = self.accel_range(&gap);
                        let (worst, best) = (demand - gap.constant - lo, demand - gap.constant - hi);
                        if worst <= 0.0 {
                            continue; // can never bind
                        }
                        let max_slack = glob_bound + if band { c.slack_bound() } else { 0.0 };
                        let unconditional = p.ego.occupancy.contains(l);
                        if best > max_slack + tol {
                            if unconditional {
                                return Err(Infeasible);
                            }
                            // The ego can never be in lane l at this step: forbid it outright.
                            for j in 0..=s {
                                self.m.col_upper[self.cols.lane[j][(l - 1) as usize]] = 0.0;
                            }
                            continue;
                        }
                        let cell = i * h_len + s;
                        let mut row = gap;
                        if band {
                            let bound = c.slack_bound();
                            let col = match self.cols.hys[cell] {
                                Some(col) => col,
                                None => *self.cols.hys[cell].insert(self.m.add_col(w.w_slack, 0.0, bound, false)),
                            };
                            row = row.term(col, 1.0);
                        }
                        if self.mode == Mode::Relaxed {
                            let col = match self.cols.glob[cell] {
                                Some(col) => col,
                                None => {
                                    *self.cols.glob[cell].insert(self.m.add_col(w.w_global, 0.0, c.relax_bound, false))
                                }
                            };
                            row = row.term(col, 1.0);
                        }
                        if !unconditional {
                            // Off (o = 0) the row relaxes by its worst violation.
                            let o = self.occupancy(s, (l - 1) as usize);
                            row = row.term(o, -worst);
                            row.constant += worst;
                        }
                        self.at_least(row, demand);
                    }
                }
            }
        }
        Ok(())
    }

    fn occupancy_rows(&mut self) {
        for s in 0..self.problem.horizon {
            for l in 0..self.problem.lanes as usize {
                if let Some(o) = self.cols.occ[s][l] {
                    for j in 0..=s {
                        let z = self.cols.lane[j][l];
                        self.at_least(Expr::default().term(o, 1.0).term(z, -1.0), 0.0);
                    }
                }
            }
        }
    }
}

fn build(problem: &Problem, mode: Mode) -> Result<(MipModel, Columns), Infeasible> {
    let mut b = Builder::new(problem, mode);
    b.step_columns();
    b.action_rows();
    b.transition_rows();
    b.lane_change_rows();
    b.input_rows();
    b.speed_rows();
    b.safety_rows()?;
    b.occupancy_rows();
    Ok((b.m, b.cols))
}

/// The actions and accelerations of a solution.
fn decode(problem: &Problem, cols: &Columns, values: &[f64]) -> (Vec<Action>, Vec<f64>) {
    let on = |c: usize| values[c] > 0.5;
    let actions = (0..problem.horizon)
        .map(|s| {
            let act = cols.act[s];
            let pick = |neg: usize, pos: usize| {
                if on(act[neg]) {
                    -1
                } else if on(act[pos]) {
                    1
                } else {
                    0
                }
            };
            Action {
                lateral: pick(0, 1),
                longitudinal: pick(2, 3),
            }
        })
        .collect();
    let accel = cols.accel.iter().map(|&c| values[c]).collect();
    (actions, accel)
}

mod backend;
mod branch;
pub use backend::{LayerOutcome, MilpBackend};

#[cfg(test)]
#[path = "milp_tests.rs"]
mod tests;

#[cfg(test)]
mod fingerprint_tests;
