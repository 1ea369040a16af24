//! The decision problem as a MILP on HiGHS (paper III-E, III-F), built one constraint family
//! at a time so that each function sits beside its equations:
//!
//! - [`Builder::step_columns`]: per step `s` (action `s`, state `s + 1`) the action binaries
//!   `L-, L+, G-, G+`, the lane one-hot `z[s][l]`, the beta one-hot `b[s][j]`, the kinematic
//!   input `u[s]` and the columns of the speed and comfort prices;
//! - [`Builder::action_rows`]: at most one change per step (one per direction with combined
//!   actions);
//! - [`Builder::transition_rows`]: one-hots linked to the previous step by transition flows
//!   whose up / down parts are the actions (a network flow: its LP relaxation is tight), so
//!   `clip` is implicit (values outside the one-hots do not exist);
//! - [`Builder::lane_change_rows`]: a plan targets at most one lane the ego does not occupy
//!   now, and none while a lane change is under way (`model::new_lanes_allowed`);
//! - [`Builder::input_rows`]: `u[s]` inside the range of the state it is in;
//! - [`Builder::speed_rows`]: the acceleration LP's speed limit and price rows
//!   (`lp::accel::Step`); position and speed are affine in `u` and substituted, not columns;
//! - [`Builder::safety_rows`]: per SV, step and lane the tightest branch's rows, switched on
//!   by the occupancy `o[s][l]` with a big-M from the bounds of `u` (rows that can never bind
//!   are dropped, lanes that can never be safe are fixed off), the hysteresis band with its
//!   slack, and Layer A's global slack (`lp::accel::Slacks`);
//! - [`Builder::occupancy_rows`]: `o[s][l] >= z[j][l]` for `j <= s`: a lane stays occupied
//!   once targeted because a lane change outlasts the horizon (with the paper's
//!   `PlanOccupancy::TargetLane` the occupancy is `z[s][l]` itself).
//!
//! [`MilpBackend`] solves a layer's LP relaxation first and runs the MIP only when the
//! relaxation does not settle it (`backend.rs`).

use crate::config::PlanOccupancy;
use crate::evaluate::Mode;
use crate::highs_solver::MipModel;
use crate::lp::accel::{Cell, Slacks, Step};
use crate::lp::{Col, Expr, HighsSink, PriceCols, Sink};
use crate::problem::{Problem, SvConstraint};
use crate::types::Action;

/// An entry of a one-hot: a column, or a value known before the solve.
#[derive(Debug, Clone, Copy)]
enum OneHot {
    Column(Col),
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
    col: Col,
}

/// The action binaries, one per step each.
#[derive(Debug, Clone, Default)]
struct ActionCols {
    /// `L-`: a lane change to the left.
    lane_left: Vec<Col>,
    /// `L+`: to the right.
    lane_right: Vec<Col>,
    /// `G-`: beta one down.
    beta_down: Vec<Col>,
    /// `G+`: beta one up.
    beta_up: Vec<Col>,
}

/// The columns of one built model.
#[derive(Debug, Clone)]
struct Columns {
    act: ActionCols,
    /// Lane one-hot per step, index `l - 1`.
    lane: Vec<Vec<Col>>,
    /// Beta one-hot per step, index `beta + 1`.
    beta: Vec<[Col; 3]>,
    /// Transition flows of both chains.
    flows: Vec<Flow>,
    /// Kinematic input per step.
    accel: Vec<Col>,
    /// The speed and braking prices per step.
    prices: Vec<PriceCols>,
    /// Occupancy column per step and lane, when some row needs it.
    occ: Vec<Vec<Option<Col>>>,
    /// `(lane index, column)`: whether the plan visits a lane the ego does not occupy now.
    seen: Vec<(usize, Col)>,
    /// Hysteresis and global slack per SV and step.
    slacks: Slacks,
}

/// The layer is infeasible before any solve.
struct Infeasible;

/// Builds the model of one layer.
struct Builder<'p> {
    problem: &'p Problem,
    b: HighsSink,
    cols: Columns,
}

impl<'p> Builder<'p> {
    fn new(problem: &'p Problem, mode: Mode) -> Self {
        let (h, n) = (problem.horizon, problem.lanes as usize);
        Self {
            problem,
            b: HighsSink::default(),
            cols: Columns {
                act: ActionCols::default(),
                lane: Vec::with_capacity(h),
                beta: Vec::with_capacity(h),
                flows: Vec::new(),
                accel: Vec::with_capacity(h),
                prices: Vec::with_capacity(h),
                occ: vec![vec![None; n]; h],
                seen: Vec::new(),
                slacks: Slacks::new(problem, mode),
            },
        }
    }

    /// `v[s] - v0 = dt sum_{j <= s} u[j]`.
    fn speed_change(&self, s: usize) -> Expr {
        let dt = self.problem.kin.dt;
        self.cols.accel[..=s].iter().map(|&u| u * dt).sum()
    }

    /// Ego position after step `s`.
    fn position(&self, s: usize) -> Expr {
        let kin = &self.problem.kin;
        let mut x = Expr::constant(kin.coasting_position(&self.problem.ego, s));
        x.extend((0..=s).map(|j| self.cols.accel[j] * kin.position_gain(s, j)));
        x
    }

    fn step_columns(&mut self) {
        let p = self.problem;
        let w = &p.weights;
        let (u_min, u_max) = p.kin.extreme_accels();
        for s in 0..p.horizon {
            let last = s + 1 == p.horizon;
            let act = &mut self.cols.act;
            act.lane_left.push(self.b.binary(w.w_lane_change));
            act.lane_right.push(self.b.binary(w.w_lane_change));
            act.beta_down.push(self.b.binary(w.w_switch));
            act.beta_up.push(self.b.binary(w.w_switch));
            // The terminal lane value is charged on the last step's lane.
            let lane = (0..p.lanes as usize)
                .map(|l| self.b.binary(if last { p.lane_value[l] } else { 0.0 }))
                .collect();
            // The terminal state price is charged on the last step's state.
            let beta = std::array::from_fn::<_, 3, _>(|b| {
                let terminal = if last { w.w_beta_terminal[b] } else { 0.0 };
                self.b.binary(w.w_beta[b] + terminal)
            });
            self.cols.lane.push(lane);
            self.cols.beta.push(beta);
            self.cols.accel.push(self.b.col(0.0, u_min, u_max));
            let prices = self.b.price_columns(&Step::at(p, &self.cols.accel, s));
            self.cols.prices.push(prices);
        }
    }

    fn action_rows(&mut self) {
        let act = &self.cols.act;
        for s in 0..self.problem.horizon {
            let (left, right, down, up) = (act.lane_left[s], act.lane_right[s], act.beta_down[s], act.beta_up[s]);
            if self.problem.combined_actions {
                self.b.at_most(left + right, 1.0);
                self.b.at_most(down + up, 1.0);
            } else {
                self.b.at_most(left + right + down + up, 1.0);
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
        for s in 0..self.problem.horizon {
            let act = &self.cols.act;
            let lane = (act.lane_left[s], act.lane_right[s]);
            let beta = (act.beta_down[s], act.beta_up[s]);
            let (lane_now, lane_prev) = (self.cols.lane[s].clone(), self.previous_one_hot(s, Chain::Lane));
            self.flow_rows(Chain::Lane, s, &lane_prev, &lane_now, lane);
            let (beta_now, beta_prev) = (self.cols.beta[s].to_vec(), self.previous_one_hot(s, Chain::Beta));
            self.flow_rows(Chain::Beta, s, &beta_prev, &beta_now, beta);
        }
    }

    /// The previous step's lane (or beta) one-hot: columns, or the ego's state at `s = 0`.
    fn previous_one_hot(&self, s: usize, chain: Chain) -> Vec<OneHot> {
        let p = self.problem;
        match (s, chain) {
            (0, Chain::Lane) => (1..=p.lanes).map(|l| OneHot::Fixed(l == p.ego.maneuver.lane)).collect(),
            (0, Chain::Beta) => (-1..=1).map(|b| OneHot::Fixed(b == p.ego.maneuver.beta)).collect(),
            (_, Chain::Lane) => self.cols.lane[s - 1].iter().map(|&c| OneHot::Column(c)).collect(),
            (_, Chain::Beta) => self.cols.beta[s - 1].iter().map(|&c| OneHot::Column(c)).collect(),
        }
    }

    /// Flow rows from `prev` to `now` with the `(down, up)` flows equal to the action columns.
    fn flow_rows(&mut self, chain: Chain, step: usize, prev: &[OneHot], now: &[Col], (down, up): (Col, Col)) {
        let n = now.len();
        // Rows `sum_i x[i -> j] - now[j] = 0`, `sum x[i -> j < i] - down = 0`, ...
        let mut into: Vec<Expr> = now.iter().map(|&c| Expr::from(-c)).collect();
        let (mut down_flow, mut up_flow) = (Expr::from(-down), Expr::from(-up));
        for (i, from) in prev.iter().enumerate() {
            if matches!(from, OneHot::Fixed(false)) {
                continue; // no flow leaves a state the ego is not in
            }
            let mut out = Expr::default();
            let reachable = i.saturating_sub(1)..(i + 2).min(n);
            for (j, target) in into.iter_mut().enumerate().take(reachable.end).skip(reachable.start) {
                let x = self.b.col(0.0, 0.0, 1.0);
                self.cols.flows.push(Flow {
                    chain,
                    step,
                    from: i,
                    to: j,
                    col: x,
                });
                out += x;
                *target += x;
                if j < i {
                    down_flow += x;
                } else if j > i {
                    up_flow += x;
                }
            }
            match *from {
                OneHot::Column(c) => self.b.equal(out - c, 0.0),
                _ => self.b.equal(out, 1.0),
            }
        }
        for row in into {
            self.b.equal(row, 0.0);
        }
        self.b.equal(down_flow, 0.0);
        self.b.equal(up_flow, 0.0);
    }

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
                    self.b.set_upper(self.cols.lane[s][l], 0.0);
                }
            }
            return;
        }
        let mut seen_any = Expr::default();
        for &l in &new_lanes {
            let seen = self.b.col(0.0, 0.0, 1.0);
            self.cols.seen.push((l, seen));
            for s in 0..p.horizon {
                self.b.at_least(seen - self.cols.lane[s][l], 0.0);
            }
            seen_any += seen;
        }
        self.b.at_most(seen_any, allowed as f64);
    }

    /// `sum_j lo(j) b[s][j] <= u[s] <= sum_j hi(j) b[s][j]`.
    fn input_rows(&mut self) {
        let kin = self.problem.kin;
        for s in 0..self.problem.horizon {
            let (u, beta) = (self.cols.accel[s], self.cols.beta[s]);
            let lo: Expr = beta.iter().zip(&kin.bounds).map(|(&b, &(lo, _))| b * lo).sum();
            let hi: Expr = beta.iter().zip(&kin.bounds).map(|(&b, &(_, hi))| b * hi).sum();
            self.b.at_least(u - lo, 0.0);
            self.b.at_most(u - hi, 0.0);
        }
    }

    /// The acceleration LP's speed limit (where the extreme accelerations could leave
    /// `[0, v_cap]`) and its price rows.
    fn speed_rows(&mut self) {
        let p = self.problem;
        let (u_min, u_max) = p.kin.extreme_accels();
        for s in 0..p.horizon {
            let step = Step::at(p, &self.cols.accel, s);
            let steps = (s + 1) as f64 * p.kin.dt;
            if step.limit.may_bind(steps * u_min, steps * u_max) {
                self.b.row(step.limit.bounds(), Expr::from(step.limit.change));
            }
            self.b.price_rows(&step, &self.cols.prices[s]);
        }
    }

    /// Whether the ego is in lane `l` (index) at step `s`: the lane one-hot itself when a plan
    /// occupies its target lane alone (`PlanOccupancy::TargetLane`), else a column held on
    /// once the lane is targeted ([`Builder::occupancy_rows`]).
    fn occupancy(&mut self, s: usize, l: usize) -> Col {
        if self.problem.ego.plan_occupancy == PlanOccupancy::TargetLane {
            return self.cols.lane[s][l];
        }
        match self.cols.occ[s][l] {
            Some(o) => o,
            None => *self.cols.occ[s][l].insert(self.b.col(0.0, 0.0, 1.0)),
        }
    }

    /// Rows of one SV in lane `l` at step `s`: `(gap expression, demand, is band row)`, the
    /// gap expression being the signed gap to the tightest branch without the demand.
    fn lane_rows(&self, c: &SvConstraint, s: usize, l: u8) -> Vec<(Expr, f64, bool)> {
        let p = self.problem;
        let sign = c.sign();
        let ego_gap = self.position(s) * -sign;
        let mut rows = Vec::with_capacity(3);
        let binding = c.binding_lanes(crate::lanes::LaneSet::single(l), p.ego.occupancy);
        if !binding.is_empty() {
            let in_lane: Vec<usize> = (0..c.branches.len())
                .filter(|&b| c.branches[b].occupancy[s].contains(l))
                .collect();
            // The tightest branch: the largest demand net of its position.
            let net = |b: usize, demand: f64| demand - sign * c.branches[b].x[s];
            let tightest = |demand: &dyn Fn(usize) -> f64| in_lane.iter().map(|&b| net(b, demand(b))).reduce(f64::max);
            let slope = self.speed_change(s) * -c.slope;
            if let Some(d) = tightest(&|b| c.margin[b][s]) {
                rows.push((ego_gap.clone() + slope, d - c.allowance[s] + p.length, false));
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
                let anticipated = ego_gap + self.speed_change(s) * (-sign * c.anticipation_s);
                let demand = frozen.release_m - sign * c.mean_x[s] + p.length - c.band_anticipation(s, p.ego.v);
                rows.push((anticipated, demand, true));
            }
        }
        rows
    }

    fn safety_rows(&mut self) -> Result<(), Infeasible> {
        let p = self.problem;
        let (u_min, u_max) = p.kin.extreme_accels();
        // Held: the lanes occupied now stay occupied at every step, and a lane once targeted.
        let held = p.ego.plan_occupancy == PlanOccupancy::HeldThroughChange;
        for (i, c) in p.svs.iter().enumerate() {
            let relax_bound = if self.cols.slacks.relaxed() { c.relax_bound } else { 0.0 };
            for s in 0..p.horizon {
                for l in 1..=p.lanes {
                    for (gap, demand, band) in self.lane_rows(c, s, l) {
                        // Row: gap + slacks >= demand. Its violation `demand - gap` ranges
                        // over [best, worst] as u ranges over its box.
                        let (lo, hi) = gap.range(|_| (u_min, u_max));
                        let constant = gap.constant_part();
                        let (worst, best) = (demand - constant - lo, demand - constant - hi);
                        if worst <= 0.0 {
                            continue; // can never bind
                        }
                        let max_slack = relax_bound + if band { c.slack_bound() } else { 0.0 };
                        let unconditional = held && p.ego.occupancy.contains(l);
                        if best > max_slack + p.tolerance {
                            if unconditional {
                                return Err(Infeasible);
                            }
                            // The ego can never be in lane l at this step: forbid it outright
                            // (and every earlier step in it, where a targeted lane stays held).
                            let first = if held { 0 } else { s };
                            for j in first..=s {
                                self.b.set_upper(self.cols.lane[j][(l - 1) as usize], 0.0);
                            }
                            continue;
                        }
                        let cell = Cell { sv: i, step: s };
                        let mut row = gap + self.cols.slacks.of(&mut self.b, p, cell, band);
                        if !unconditional {
                            // Off (o = 0) the row relaxes by its worst violation.
                            let o = self.occupancy(s, (l - 1) as usize);
                            row = row + o * -worst + worst;
                        }
                        self.b.at_least(row, demand);
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
                        self.b.at_least(o - self.cols.lane[j][l], 0.0);
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
    Ok((b.b.into_model(), b.cols))
}

/// The actions and accelerations of a solution.
fn decode(problem: &Problem, cols: &Columns, values: &[f64]) -> (Vec<Action>, Vec<f64>) {
    let on = |c: Col| values[c.index()] > 0.5;
    let pick = |neg: Col, pos: Col| {
        if on(neg) {
            -1
        } else if on(pos) {
            1
        } else {
            0
        }
    };
    let act = &cols.act;
    let actions = (0..problem.horizon)
        .map(|s| Action {
            lateral: pick(act.lane_left[s], act.lane_right[s]),
            longitudinal: pick(act.beta_down[s], act.beta_up[s]),
        })
        .collect();
    let accel = cols.accel.iter().map(|&c| values[c.index()]).collect();
    (actions, accel)
}

mod backend;
mod branch;
#[cfg(test)]
use backend::LayerOutcome;
pub use backend::MilpBackend;

#[cfg(test)]
#[path = "milp_tests.rs"]
mod tests;

#[cfg(test)]
mod fingerprint_tests;
