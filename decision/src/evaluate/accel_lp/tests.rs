//! The dense simplex against HiGHS on the LPs of real sequences: the corpus's situations,
//! every class of Table I, both modes, single and combined action sets, `H = 3..6`.

use super::*;
use crate::corpus::{paper_classes, SituationGenerator};
use crate::evaluate::{requirements, score};
use crate::model::rollout;
use crate::problem::prepare;
use crate::PlannerConfig;

#[derive(Debug, Default)]
struct Tally {
    optimal: usize,
    infeasible: usize,
}

/// Solve both ways, up to `per_situation` sequences of `situations` situations per class,
/// and hold the dense answer to HiGHS's: the same verdict, the same optimal objective
/// (relative 1e-7), a point inside its boxes that meets every row within 1e-7 and scores the
/// same exact cost as HiGHS's point.
fn compare(config: &PlannerConfig, situations: usize, per_situation: usize, seed: u64) -> Tally {
    let mut tally = Tally::default();
    let mut offset = 0;
    for class in paper_classes() {
        let mut generator = SituationGenerator::new(seed + u64::from(class.id));
        for _ in 0..situations {
            let s = generator.situation(config, &class);
            let problem = prepare(config, &s).problem;
            let sequences = problem.admissible_sequences();
            let stride = (sequences.len() / per_situation).max(1);
            offset += 1;
            for actions in sequences.iter().skip(offset % stride).step_by(stride) {
                let Some(r) = rollout(&problem.kin, problem.lanes, &problem.ego, actions) else {
                    continue;
                };
                let rows = requirements(&problem, &r);
                for mode in [Mode::Nominal, Mode::Relaxed] {
                    let dense = by_dense(&problem, &r, &rows, mode).expect("the dense simplex gives a verdict");
                    let highs = by_highs(&problem, &r, &rows, mode);
                    let (d, h) = match (dense, highs) {
                        (Some(d), Some(h)) => (d, h),
                        (None, None) => {
                            tally.infeasible += 1;
                            continue;
                        }
                        (d, h) => panic!("dense {d:?} vs HiGHS {h:?} for {actions:?} in {mode:?}: {s:?}"),
                    };
                    let scale = 1.0 + h.objective.abs();
                    assert!(
                        (d.objective - h.objective).abs() <= 1e-7 * scale,
                        "objective {} vs HiGHS {} for {actions:?} in {mode:?}: {s:?}",
                        d.objective,
                        h.objective
                    );
                    for (m, &a) in r.maneuvers.iter().zip(&d.accel) {
                        let (lo, hi) = problem.kin.bounds_of(m.beta);
                        assert!(a >= lo && a <= hi, "{a} outside [{lo}, {hi}]");
                    }
                    let at = |accel: &[f64], tol: f64| {
                        let r = r.with_accelerations(&problem.kin, &problem.ego, accel);
                        score(&problem, r, &rows, mode, tol)
                    };
                    let exact = at(&d.accel, 1e-7).expect("the dense point meets every row within 1e-7");
                    let reference = at(&h.accel, 1e-5).expect("HiGHS's point scores");
                    assert!(
                        (exact.cost - reference.cost).abs() <= 1e-6 * (1.0 + reference.cost.abs()),
                        "exact cost {} vs {} at HiGHS's point for {actions:?} in {mode:?}",
                        exact.cost,
                        reference.cost
                    );
                    tally.optimal += 1;
                }
            }
        }
    }
    tally
}

fn config(horizon: usize, combined: bool) -> PlannerConfig {
    let mut c = PlannerConfig::default();
    c.timing.horizon = horizon;
    c.ego.combined_actions = combined;
    c
}

fn check(tally: Tally, least: usize) {
    assert!(
        tally.optimal + tally.infeasible >= least && tally.optimal > least / 10 && tally.infeasible > least / 100,
        "{tally:?}"
    );
}

#[test]
fn dense_and_highs_agree_at_short_horizons() {
    check(compare(&config(3, false), 2, 40, 1), 2000);
    check(compare(&config(4, false), 1, 40, 2), 1000);
    check(compare(&config(3, true), 1, 40, 3), 1000);
}

/// Without a cruise band the cruising state's box is a point (`lo == hi`) next to the
/// ranged braking and accelerating states.
#[test]
fn dense_and_highs_agree_with_a_fixed_cruising_state() {
    let mut c = config(3, false);
    c.ego.cruise_band_mps2 = 0.0;
    check(compare(&c, 2, 40, 4), 2000);
}

#[test]
#[ignore = "long: H = 4..6 with combined actions (cargo test --release -- --ignored)"]
fn dense_and_highs_agree_at_long_horizons() {
    for (h, combined) in [(5, false), (6, false), (4, true), (5, true), (6, true)] {
        check(compare(&config(h, combined), 3, 60, 10 + h as u64), 3000);
    }
}
