//! The MILP against the exact oracle, row by row: every sequence the oracle finds feasible is a
//! feasible point of the model with the same objective.

use super::*;
use crate::corpus::{paper_classes, SituationGenerator};
use crate::model::admissible_sequences;
use crate::problem::prepare;
use crate::PlannerConfig;

/// Every sequence the oracle finds feasible maps to a column vector that satisfies every
/// row and bound of the MILP, with the same objective: the model cuts off nothing that
/// is allowed and charges what the exact evaluation charges.
fn oracle_points_are_milp_feasible(config: &PlannerConfig) -> usize {
    let mut checked = 0;
    for class in paper_classes() {
        let mut generator = SituationGenerator::new(99 + u64::from(class.id));
        for _ in 0..4 {
            let s = generator.situation(config, &class);
            let problem = prepare(config, &s).problem;
            let sequences = admissible_sequences(
                problem.ego.maneuver,
                problem.lanes,
                problem.horizon,
                problem.combined_actions,
            );
            for mode in [Mode::Nominal, Mode::Relaxed] {
                let Ok((model, cols)) = build(&problem, mode) else {
                    let any = sequences.iter().any(|a| evaluate(&problem, a, mode).is_some());
                    assert!(!any, "build declared infeasible, oracle disagrees: {s:?}");
                    continue;
                };
                for actions in &sequences {
                    let Some(e) = evaluate(&problem, actions, mode) else {
                        continue;
                    };
                    let x = columns_of(&problem, &cols, &e, model.num_cols());
                    for (c, &v) in x.iter().enumerate() {
                        assert!(
                            v >= model.col_lower[c] - 1e-6 && v <= model.col_upper[c] + 1e-6,
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
                            act >= model.row_lower[r] - 1e-5 && act <= model.row_upper[r] + 1e-5,
                            "row {r}: {act} outside [{}, {}] for {actions:?} in {mode:?}; {s:?}",
                            model.row_lower[r],
                            model.row_upper[r]
                        );
                    }
                    let objective: f64 = x.iter().zip(&model.col_cost).map(|(v, c)| v * c).sum();
                    assert!((objective - e.cost).abs() < 1e-5, "objective {objective} vs {}", e.cost);
                    checked += 1;
                }
            }
        }
    }
    checked
}

#[test]
fn oracle_feasible_sequences_are_milp_feasible_with_equal_cost() {
    let config = PlannerConfig::default();
    let checked = oracle_points_are_milp_feasible(&config);
    assert!(checked > 500, "{checked}");
}

#[test]
fn the_same_holds_with_combined_actions() {
    let mut config = PlannerConfig::default();
    config.ego.combined_actions = true;
    let checked = oracle_points_are_milp_feasible(&config);
    assert!(checked > 500, "{checked}");
}

#[test]
fn the_same_holds_for_the_discrete_maps() {
    let mut config = PlannerConfig::default();
    config.ego.continuous_accel = false;
    config.idm.speed_dependent = false;
    let checked = oracle_points_are_milp_feasible(&config);
    assert!(checked > 500, "{checked}");
}
