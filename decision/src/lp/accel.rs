//! The acceleration LP, written once: per step `h` the speed `v_h = v0 + dt sum_{j <= h} u_j`
//! held within `[0, v_cap]`, the price `w_v |v_h - v_des|` (plus the terminal weight on the
//! last step) and the braking prices `w_b max(0, -u_h)`, `w_hb max(0, comfort_decel - u_h)`,
//! `w_fb max(0, firm_decel - u_h)` and, when on, `w_pb max(0, peak_decel - u_h)`; per SV and
//! step the hysteresis slack of the band rows and Layer A's global slack; and the safety rows
//! `gap(u) + slacks >= demand`.
//!
//! The exact evaluation builds the whole LP of one fixed sequence from it ([`describe`]);
//! the MILP builds its speed terms ([`Step`]) and slack columns ([`Slacks`]) from it and adds
//! its binaries, flows and big-M switches around them. A sink lays the terms out for its
//! solver ([`AccelSink`]): HiGHS gets a column and rows per price, the dense simplex its exact
//! reductions of them.

use std::ops::{Index, IndexMut, RangeInclusive};

use super::{Col, Expr, Linear, Scaled, Sink};
use crate::evaluate::{Mode, Requirement};
use crate::model::Rollout;
use crate::problem::Problem;

/// `weight * max(0, base + terms)`.
#[derive(Debug, Clone, Copy)]
pub struct Price<'a> {
    pub weight: f64,
    pub base: f64,
    pub terms: Scaled<'a>,
}

/// `weight * |value + offset - target|`.
#[derive(Debug, Clone, Copy)]
pub struct AbsPrice<'a> {
    pub weight: f64,
    pub value: Scaled<'a>,
    pub offset: f64,
    pub target: f64,
}

impl<'a> AbsPrice<'a> {
    /// The two halves `max(0, value + offset - target)` and `max(0, target - offset - value)`,
    /// in that order.
    pub fn halves(&self) -> [Price<'a>; 2] {
        [
            Price {
                weight: self.weight,
                base: self.offset - self.target,
                terms: self.value,
            },
            Price {
                weight: self.weight,
                base: self.target - self.offset,
                terms: -self.value,
            },
        ]
    }
}

/// `0 <= v0 + change <= cap`, a row on `change` within `[-v0, cap - v0]`.
#[derive(Debug, Clone, Copy)]
pub struct SpeedLimit<'a> {
    pub change: Scaled<'a>,
    pub v0: f64,
    pub cap: f64,
}

impl SpeedLimit<'_> {
    /// Whether the row can bind when `change` ranges over `[lo, hi]`.
    pub fn may_bind(&self, lo: f64, hi: f64) -> bool {
        self.v0 + lo < 0.0 || self.v0 + hi > self.cap
    }

    pub fn bounds(&self) -> RangeInclusive<f64> {
        -self.v0..=self.cap - self.v0
    }
}

/// What step `h` charges and bounds.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    pub limit: SpeedLimit<'a>,
    /// `|v_h - v_des|`.
    pub deviation: AbsPrice<'a>,
    /// Braking beyond zero, beyond `comfort_decel`, beyond `firm_decel`.
    pub brakes: [Price<'a>; 3],
    /// Braking beyond `peak_decel`, when priced (absent at weight 0: the model of a
    /// configuration without it is the one it always was).
    pub peak: Option<Price<'a>>,
}

impl<'a> Step<'a> {
    /// Step `h` over the accelerations `u` (`u[..=h]` must exist).
    pub fn at(problem: &Problem, u: &'a [Col], h: usize) -> Self {
        let w = &problem.weights;
        let (dt, v0) = (problem.kin.dt, problem.ego.v);
        // v_h - v0 = dt sum_{j <= h} u_j.
        let change = Scaled {
            cols: &u[..=h],
            coef: dt,
        };
        let terminal = if h + 1 == problem.horizon {
            w.w_speed_terminal
        } else {
            0.0
        };
        let brake = |weight: f64, base: f64| Price {
            weight,
            base,
            terms: Scaled {
                cols: &u[h..=h],
                coef: -1.0,
            },
        };
        Step {
            deviation: AbsPrice {
                weight: w.w_speed + terminal,
                value: change,
                offset: v0,
                target: problem.desired_speed,
            },
            limit: SpeedLimit {
                change,
                v0,
                cap: problem.speed_cap,
            },
            brakes: [
                brake(w.w_brake, 0.0),
                brake(w.w_hard_brake, problem.comfort_decel),
                brake(w.w_firm_brake, problem.firm_decel),
            ],
            peak: (w.w_peak_brake > 0.0).then(|| brake(w.w_peak_brake, problem.peak_decel)),
        }
    }
}

/// An SV and a step, 0-based.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Cell {
    pub sv: usize,
    pub step: usize,
}

/// One value per SV and step.
#[derive(Debug, Clone)]
pub struct CellMap<T> {
    horizon: usize,
    items: Vec<T>,
}

impl<T: Clone> CellMap<T> {
    pub fn new(svs: usize, horizon: usize, value: T) -> Self {
        Self {
            horizon,
            items: vec![value; svs * horizon],
        }
    }
}

#[cfg(test)]
impl<T> CellMap<T> {
    pub fn iter(&self) -> impl Iterator<Item = (Cell, &T)> {
        let h = self.horizon;
        self.items.iter().enumerate().map(move |(i, v)| {
            let cell = Cell { sv: i / h, step: i % h };
            (cell, v)
        })
    }
}

impl<T> Index<Cell> for CellMap<T> {
    type Output = T;
    fn index(&self, c: Cell) -> &T {
        &self.items[c.sv * self.horizon + c.step]
    }
}

impl<T> IndexMut<Cell> for CellMap<T> {
    fn index_mut(&mut self, c: Cell) -> &mut T {
        &mut self.items[c.sv * self.horizon + c.step]
    }
}

/// The slack columns per SV and step, made when a row first needs them: the hysteresis
/// slack (`w_s` per metre, up to the SV's slack bound) of the band rows, and in Layer A the
/// global slack (`w_q`, up to `gamma d_idm`) of every safety row.
#[derive(Debug, Clone)]
pub struct Slacks {
    pub hysteresis: CellMap<Option<Col>>,
    pub global: CellMap<Option<Col>>,
    relaxed: bool,
}

impl Slacks {
    pub fn new(problem: &Problem, mode: Mode) -> Self {
        let (n, h) = (problem.svs.len(), problem.horizon);
        Self {
            hysteresis: CellMap::new(n, h, None),
            global: CellMap::new(n, h, None),
            relaxed: mode == Mode::Relaxed,
        }
    }

    /// Whether every safety row has the global slack (Layer A).
    pub fn relaxed(&self) -> bool {
        self.relaxed
    }

    /// The slacks a safety row of `cell` may use (a band row: the hysteresis slack too).
    pub fn of(&mut self, sink: &mut impl Sink, problem: &Problem, cell: Cell, band: bool) -> RowSlacks {
        let (w, c) = (&problem.weights, &problem.svs[cell.sv]);
        RowSlacks {
            hysteresis: band
                .then(|| *self.hysteresis[cell].get_or_insert_with(|| sink.col(w.w_slack, 0.0, c.slack_bound()))),
            global: self
                .relaxed
                .then(|| *self.global[cell].get_or_insert_with(|| sink.col(w.w_global, 0.0, c.relax_bound))),
        }
    }
}

/// The slack columns of one safety row, added to it by `+` (hysteresis first).
#[derive(Debug, Clone, Copy)]
pub struct RowSlacks {
    pub hysteresis: Option<Col>,
    pub global: Option<Col>,
}

impl Linear for RowSlacks {
    fn add_to(self, e: &mut Expr, negate: bool) {
        let cols = self.hysteresis.into_iter().chain(self.global);
        e.extend(cols.map(|c| if negate { -c } else { c * 1.0 }));
    }
}

/// How a solver's model takes the acceleration LP's terms.
pub trait AccelSink: Sink {
    /// Step `h`'s speed limit and prices.
    fn step(&mut self, step: Step<'_>);

    /// Whether the safety row `gap >= demand` is kept (before its slacks are made).
    fn keeps(&self, gap: &Expr, demand: f64) -> bool;

    /// `row >= demand`, its slacks included.
    fn safety_row(&mut self, row: Expr, demand: f64);
}

/// The LP of the best accelerations of the sequence rolled out in `r`, with the safety rows
/// `rows`, into `sink`; the accelerations' columns, one per step.
pub fn describe(
    problem: &Problem,
    r: &Rollout,
    rows: &[Requirement],
    mode: Mode,
    sink: &mut impl AccelSink,
) -> Vec<Col> {
    let u: Vec<Col> = r
        .maneuvers
        .iter()
        .map(|m| {
            let (lo, hi) = problem.kin.bounds_of(m.beta);
            sink.col(0.0, lo, hi)
        })
        .collect();
    for h in 0..problem.horizon {
        sink.step(Step::at(problem, &u, h));
    }
    let mut slacks = Slacks::new(problem, mode);
    // One buffer for the rows' gaps: most rows are dropped by a sink that reduces.
    let mut gap = Expr::default();
    for row in rows {
        gap.clear();
        gap.extend(row.coef.iter().zip(&u).map(|(&k, &c)| c * k));
        if sink.keeps(&gap, row.rhs) {
            let cell = Cell {
                sv: row.sv,
                step: row.step,
            };
            let mut full = Expr::with_capacity(gap.terms().len() + 2);
            full += &gap;
            full += slacks.of(sink, problem, cell, row.band);
            sink.safety_row(full, row.rhs);
        }
    }
    u
}
