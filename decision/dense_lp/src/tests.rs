//! The dense simplex against HiGHS on hand-made degenerate LPs and on random ones, and on
//! chains of re-solves from a parent's tableau.

use crate::simplex::*;
use highs::{HighsModelStatus, RowProblem, Sense};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const INF: f64 = f64::INFINITY;

/// The workspace links every binary with `--wrap` of HiGHS's physical core count
/// (`.cargo/config.toml`, `decision/src/highs_cores.rs`); this test binary links HiGHS without
/// `decision`, so it answers the wrapped call itself. HiGHS only logs the number (and would
/// size its thread pool by it with `threads = 0`; these tests set 1). Unused where the
/// flag is not set.
#[no_mangle]
extern "C" fn __wrap__ZN5highs8parallel20available_core_countEv() -> u32 {
    1
}

/// HiGHS's verdict on the same LP: `Some(objective)` or `None` (infeasible). HiGHS takes a
/// column once per row: repeated ones are summed (in order) and zeros dropped.
pub(crate) fn by_highs(lp: &DenseLp) -> Option<f64> {
    let mut problem = RowProblem::default();
    let cols: Vec<_> = (0..lp.num_cols())
        .map(|c| {
            let (lo, hi) = lp.bounds(c);
            problem.add_column(lp.cost(c), lo..=hi)
        })
        .collect();
    for r in 0..lp.num_rows() {
        let mut terms = lp.row_terms(r).to_vec();
        terms.sort_by_key(|t| t.0);
        let mut merged: Vec<(usize, f64)> = Vec::new();
        for (c, a) in terms {
            match merged.last_mut() {
                Some(last) if last.0 == c => last.1 += a,
                _ => merged.push((c, a)),
            }
        }
        let (lo, hi) = lp.row_bounds(r);
        let row: Vec<_> = merged
            .into_iter()
            .filter(|t| t.1 != 0.0)
            .map(|(c, a)| (cols[c], a))
            .collect();
        problem.add_row(lo..=hi, row);
    }
    let mut model = problem.optimise(Sense::Minimise);
    model.make_quiet();
    model.set_option("presolve", "off");
    model.set_option("threads", 1);
    let solved = model.solve();
    match solved.status() {
        HighsModelStatus::Optimal => Some(solved.objective_value() + lp.objective_constant()),
        HighsModelStatus::Infeasible => None,
        other => panic!("HiGHS: {other:?}"),
    }
}

/// Solve densely, check the point, and compare with HiGHS.
fn agree(lp: &DenseLp) -> Option<f64> {
    agree_with(lp, Pricing::LargestViolation)
}

/// [`agree`] with the given pivot rules.
pub(crate) fn agree_with(lp: &DenseLp, pricing: Pricing) -> Option<f64> {
    checked(lp, &lp.solve_with(pricing).expect("dense simplex"))
}

/// Check the dense outcome's point against `lp` and its verdict against HiGHS's.
fn checked(lp: &DenseLp, dense: &LpOutcome) -> Option<f64> {
    let highs = by_highs(lp);
    match (dense, highs) {
        (LpOutcome::Optimal { x, objective }, Some(h)) => {
            assert!(
                (objective - h).abs() <= 1e-7 * (1.0 + h.abs()),
                "{objective} vs HiGHS {h}: {lp:?}"
            );
            assert!((lp.objective(x) - objective).abs() <= 1e-9 * (1.0 + h.abs()));
            for (c, &v) in x.iter().enumerate() {
                let (lo, hi) = lp.bounds(c);
                assert!(v >= lo && v <= hi, "column {c} = {v} outside [{lo}, {hi}]");
            }
            for r in 0..lp.num_rows() {
                let (lo, hi) = lp.row_bounds(r);
                let a = lp.activity(r, x);
                assert!(
                    a >= lo - 1e-9 && a <= hi + 1e-9,
                    "row {r}: {a} outside [{lo}, {hi}]: {lp:?}"
                );
            }
            Some(*objective)
        }
        (LpOutcome::Infeasible, None) => None,
        (d, h) => panic!("dense {d:?} vs HiGHS {h:?}: {lp:?}"),
    }
}

#[test]
fn fixed_boxes_leave_only_the_rows_to_check() {
    let mut lp = DenseLp::default();
    let u = [lp.add_col(0.0, -2.0, -2.0), lp.add_col(0.0, 1.0, 1.0)];
    let t = lp.add_col(3.0, 0.0, INF);
    lp.add_row(0.5, INF, &[(t, 1.0), (u[0], 1.0), (u[1], 1.0)]);
    lp.add_row(-1.5, INF, &[(u[0], 1.0), (u[1], 1.0)]);
    assert_eq!(agree(&lp), Some(4.5));
    lp.add_row(-0.5, INF, &[(u[0], 1.0), (u[1], 1.0)]);
    assert_eq!(agree(&lp), None);
}

#[test]
fn duplicated_and_redundant_rows_are_degenerate_not_harmful() {
    let mut lp = DenseLp::default();
    let u: Vec<usize> = (0..4).map(|_| lp.add_col(0.0, -3.0, 2.0)).collect();
    let dev = lp.add_col(1.0, 0.0, INF);
    // dev >= 1 - sum u, repeated; the same row in several scalings; rows the boxes satisfy.
    for scale in [1.0, 1.0, 2.0, 0.5, 1.0] {
        let mut terms: Vec<(usize, f64)> = u.iter().map(|&c| (c, scale)).collect();
        terms.push((dev, scale));
        lp.add_row(scale, INF, &terms);
    }
    for &c in &u {
        lp.add_row(-3.0, 2.0, &[(c, 1.0)]);
        lp.add_row(-10.0, INF, &[(c, 1.0), (u[0], 1.0)]);
    }
    // A row that forces the first acceleration down ties with the others at zero cost.
    lp.add_row(-INF, -1.0, &[(u[0], 1.0), (u[1], 0.0)]);
    lp.add_row(-INF, -1.0, &[(u[0], 1.0)]);
    assert_eq!(agree(&lp), Some(0.0));
}

#[test]
fn an_infeasible_row_set_is_reported_infeasible() {
    let mut lp = DenseLp::default();
    let u = [lp.add_col(0.0, -4.0, 1.0), lp.add_col(0.0, -4.0, 1.0)];
    let s = lp.add_col(5.0, 0.0, 0.5);
    // u0 + u1 + s >= 1.6 needs u0 + u1 >= 1.1, but u0 - u1 >= 1 and u1 >= 0.2 leave u0 >= 1.2.
    lp.add_row(1.6, INF, &[(u[0], 1.0), (u[1], 1.0), (s, 1.0)]);
    lp.add_row(1.0, INF, &[(u[0], 1.0), (u[1], -1.0)]);
    lp.add_row(0.2, INF, &[(u[1], 1.0)]);
    assert_eq!(agree(&lp), None);
    // Equality rows that contradict each other.
    let mut lp = DenseLp::default();
    let x = lp.add_col(1.0, -INF, INF);
    lp.add_row(1.0, 1.0, &[(x, 1.0)]);
    lp.add_row(2.0, 2.0, &[(x, 1.0)]);
    assert_eq!(lp.solve(), Err(Error::NoDualStart(x)));
    let mut lp = DenseLp::default();
    let x = lp.add_col(1.0, 0.0, INF);
    lp.add_row(1.0, 1.0, &[(x, 1.0)]);
    lp.add_row(2.0, 2.0, &[(x, 1.0)]);
    assert_eq!(agree(&lp), None);
}

#[test]
fn a_direction_unbounded_by_the_rows_is_bounded_by_the_boxes() {
    // Minimise -u0 - 2 u1 (the boxes hold it) with a row that only bounds u0 - u1 below.
    let mut lp = DenseLp::default();
    let u = [lp.add_col(-1.0, -2.0, 1.5), lp.add_col(-2.0, -2.0, 0.5)];
    lp.add_row(-1.0, INF, &[(u[0], 1.0), (u[1], -1.0)]);
    assert_eq!(agree(&lp), Some(-2.5));
    // A cost that pulls a column towards an infinite bound cannot start the dual simplex.
    let t = lp.add_col(-1.0, 0.0, INF);
    lp.add_row(0.0, INF, &[(t, 1.0), (u[0], 1.0)]);
    assert_eq!(lp.solve(), Err(Error::NoDualStart(t)));
}

#[test]
fn a_constant_and_costs_added_later_count() {
    let mut lp = DenseLp::default();
    let u = lp.add_col(0.0, -1.0, 1.0);
    lp.add_cost(u, -2.0);
    lp.add_constant(7.0);
    assert_eq!(agree(&lp), Some(5.0));
}

/// A random LP shaped like the evaluation's: boxed accelerations (some fixed), hinge columns
/// with non-negative costs, bounded slack columns, rows that repeat with different right-hand
/// sides, cumulative speed rows.
fn random_lp(rng: &mut ChaCha8Rng) -> DenseLp {
    let mut lp = DenseLp::default();
    let h = rng.random_range(1..=6);
    let u: Vec<usize> = (0..h)
        .map(|_| {
            let lo = [-4.0, -2.0, -0.5, 0.0, 1.0][rng.random_range(0..5)];
            let hi = if rng.random_bool(0.3) {
                lo
            } else {
                lo + rng.random_range(0.5..3.0)
            };
            lp.add_col(0.0, lo, hi)
        })
        .collect();
    for s in 0..h {
        let speed: Vec<(usize, f64)> = u[..=s].iter().map(|&c| (c, 0.4)).collect();
        lp.add_row(-15.0, 2.0, &speed);
        let dev = lp.add_col(rng.random_range(0.0..3.0), 0.0, INF);
        let target = rng.random_range(-2.0..2.0);
        let mut up = speed.clone();
        up.push((dev, 1.0));
        lp.add_row(target, INF, &up);
        let mut down: Vec<(usize, f64)> = speed.iter().map(|&(c, a)| (c, -a)).collect();
        down.push((dev, 1.0));
        lp.add_row(-target, INF, &down);
        let brake = lp.add_col([0.0, 1.0, 20.0][rng.random_range(0..3)], 0.0, INF);
        lp.add_row(rng.random_range(-3.0..0.0), INF, &[(brake, 1.0), (u[s], 1.0)]);
    }
    let cells = rng.random_range(0..6);
    for _ in 0..cells {
        let step = rng.random_range(0..h);
        let slope = rng.random_range(-0.5..0.5);
        let slack = rng
            .random_bool(0.5)
            .then(|| lp.add_col(rng.random_range(1.0..100.0), 0.0, rng.random_range(0.0..2.0)));
        let coef: Vec<(usize, f64)> = (0..=step)
            .map(|j| (u[j], -0.16 * ((step - j) as f64 + 0.5) - slope))
            .collect();
        for _ in 0..rng.random_range(1..5) {
            let mut terms = coef.clone();
            terms.extend(slack.map(|c| (c, 1.0)));
            lp.add_row(rng.random_range(-1.5..1.0), INF, &terms);
        }
    }
    lp
}

/// `count` random LPs from `generate` agree with HiGHS under both pivot rules; returns the
/// numbers of optimal and infeasible ones (the same under both rules).
fn random_lps_agree(seed: u64, count: usize, generate: fn(&mut ChaCha8Rng) -> DenseLp) -> (usize, usize) {
    let mut tally = Vec::new();
    for pricing in [Pricing::LargestViolation, Pricing::SteepestEdge] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let optimal = (0..count)
            .filter(|_| agree_with(&generate(&mut rng), pricing).is_some())
            .count();
        tally.push((optimal, count - optimal));
    }
    assert_eq!(tally[0], tally[1]);
    tally[0]
}

#[test]
fn random_evaluation_shaped_lps_agree_with_highs() {
    let (optimal, infeasible) = random_lps_agree(11, 4000, random_lp);
    assert!(
        optimal > 500 && infeasible > 500,
        "{optimal} optimal, {infeasible} infeasible"
    );
}

/// A random relaxation shaped like the MILP's: `[0, 1]` one-hots (each summing to 1) with a
/// priced change between steps, a boxed input, big-M rows switched by the one-hots, where
/// flipping a box instead of pivoting it in is the common move.
fn random_relaxation(rng: &mut ChaCha8Rng) -> DenseLp {
    let mut lp = DenseLp::default();
    let steps = rng.random_range(1..=4);
    let width = rng.random_range(2..=4);
    let mut previous: Option<Vec<usize>> = None;
    for _ in 0..steps {
        let hot: Vec<usize> = (0..width)
            .map(|_| lp.add_col(rng.random_range(-1.0..3.0), 0.0, 1.0))
            .collect();
        let ones: Vec<(usize, f64)> = hot.iter().map(|&c| (c, 1.0)).collect();
        lp.add_row(1.0, 1.0, &ones);
        if let Some(prev) = &previous {
            // A change costs: |hot - prev| <= change, change priced.
            for (&a, &b) in hot.iter().zip(prev) {
                let change = lp.add_col(rng.random_range(0.0..2.0), 0.0, 1.0);
                lp.add_row(0.0, INF, &[(change, 1.0), (a, 1.0), (b, -1.0)]);
            }
        }
        let u = lp.add_col(0.0, -4.0, 2.0);
        if rng.random_bool(0.2) {
            // A least input, beyond the box now and then: an infeasible relaxation.
            lp.add_row(rng.random_range(0.0..2.5), INF, &[(u, 1.0)]);
        }
        let dev = lp.add_col(rng.random_range(0.1..2.0), 0.0, INF);
        let target = rng.random_range(-3.0..2.0);
        lp.add_row(target, INF, &[(dev, 1.0), (u, 1.0)]);
        lp.add_row(-target, INF, &[(dev, 1.0), (u, -1.0)]);
        for &h in &hot {
            if rng.random_bool(0.5) {
                // u <= gap + M (1 - hot): a margin that binds only in that lane.
                let m = 6.0;
                lp.add_row(-INF, rng.random_range(-3.0..2.0) + m, &[(u, 1.0), (h, m)]);
            }
        }
        previous = Some(hot);
    }
    lp
}

#[test]
fn random_relaxation_shaped_lps_agree_with_highs() {
    let (optimal, infeasible) = random_lps_agree(23, 3000, random_relaxation);
    assert!(
        optimal > 500 && infeasible > 50,
        "{optimal} optimal, {infeasible} infeasible"
    );
}

/// A branch and bound's re-solves: each LP is solved from its parent's final tableau after
/// one `[0, 1]` column of the parent's point is fixed, down to three levels, and must match
/// HiGHS on the child LP solved from scratch.
#[test]
fn restarts_from_a_parents_tableau_agree_with_highs() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (mut restarts, mut infeasible) = (0, 0);
    for _ in 0..1500 {
        let mut lp = random_relaxation(&mut rng);
        let (mut outcome, mut tableau) = lp.solve_from(Pricing::SteepestEdge, None).expect("dense simplex");
        checked(&lp, &outcome);
        for _depth in 0..3 {
            let (LpOutcome::Optimal { x, .. }, Some(parent)) = (&outcome, &tableau) else {
                break;
            };
            let free: Vec<usize> = (0..lp.num_cols()).filter(|&c| lp.bounds(c) == (0.0, 1.0)).collect();
            if free.is_empty() {
                break;
            }
            let c = free[rng.random_range(0..free.len())];
            // Mostly against the parent's point (the usual branch), now and then with it.
            let fixed = if rng.random_bool(0.8) {
                (1.0 - x[c]).round()
            } else {
                x[c].round()
            };
            lp.set_bounds(c, fixed, fixed);
            assert!(parent.0.clone().restart(&lp), "a fixed box keeps every bound finite");
            (outcome, tableau) = lp
                .solve_from(Pricing::SteepestEdge, Some(parent.clone()))
                .expect("dense simplex");
            restarts += 1;
            infeasible += usize::from(checked(&lp, &outcome).is_none());
        }
    }
    assert!(
        restarts > 2000 && infeasible > 100,
        "{restarts} restarts, {infeasible} infeasible"
    );
}
