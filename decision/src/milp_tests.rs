//! The MILP against the exact oracle, row by row: every sequence the oracle finds feasible is a
//! feasible point of the model with the same objective.

use super::*;
use crate::corpus::{paper_classes, SituationGenerator};
use crate::evaluate::{evaluate, Evaluation};
use crate::highs_solver::MipStatus;
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
            let sequences = problem.admissible_sequences();
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

#[test]
fn the_same_holds_when_a_plan_occupies_its_target_lane_alone() {
    let mut config = PlannerConfig::default();
    config.ego.plan_occupancy = crate::PlanOccupancy::TargetLane;
    let checked = oracle_points_are_milp_feasible(&config);
    assert!(checked > 500, "{checked}");
}

#[test]
fn the_same_holds_with_a_price_beyond_the_peak_braking() {
    let mut config = PlannerConfig::default();
    config.cost.w_peak_brake = 20.0;
    let checked = oracle_points_are_milp_feasible(&config);
    assert!(checked > 500, "{checked}");
}

#[test]
fn the_same_holds_with_terminal_state_prices() {
    let mut config = PlannerConfig::default();
    config.cost.w_beta_terminal = [2.0, 0.5, 3.0];
    let checked = oracle_points_are_milp_feasible(&config);
    assert!(checked > 500, "{checked}");
}

/// Column vector of a sequence already evaluated feasible (to check the model against the
/// oracle).
fn columns_of(problem: &Problem, cols: &Columns, e: &Evaluation, num_cols: usize) -> Vec<f64> {
    let mut x = vec![0.0; num_cols];
    let mut set = |c: Col, v: f64| x[c.index()] = v;
    let r = &e.rollout;
    let act = &cols.act;
    for s in 0..problem.horizon {
        let a = r.actions[s];
        match a.lateral {
            -1 => set(act.lane_left[s], 1.0),
            1 => set(act.lane_right[s], 1.0),
            _ => {}
        }
        match a.longitudinal {
            -1 => set(act.beta_down[s], 1.0),
            1 => set(act.beta_up[s], 1.0),
            _ => {}
        }
        set(cols.lane[s][(r.maneuvers[s].lane - 1) as usize], 1.0);
        set(cols.beta[s][(r.maneuvers[s].beta + 1) as usize], 1.0);
        set(cols.accel[s], r.accel[s]);
        let prices = &cols.prices[s];
        set(prices.deviation, (problem.desired_speed - r.v[s]).abs());
        let [brake, hard, firm] = prices.brakes;
        set(brake, (-r.accel[s]).max(0.0));
        set(hard, (problem.comfort_decel - r.accel[s]).max(0.0));
        set(firm, (problem.firm_decel - r.accel[s]).max(0.0));
        if let Some(peak) = prices.peak {
            set(peak, (problem.peak_decel - r.accel[s]).max(0.0));
        }
        for (l, o) in cols.occ[s].iter().enumerate() {
            if let Some(o) = *o {
                set(o, f64::from(u8::from(r.occupancy[s].contains((l + 1) as u8))));
            }
        }
    }
    let state = |chain: Chain, s: Option<usize>| {
        let m = s.map_or(problem.ego.maneuver, |s| r.maneuvers[s]);
        match chain {
            Chain::Lane => (m.lane - 1) as usize,
            Chain::Beta => (m.beta + 1) as usize,
        }
    };
    for f in &cols.flows {
        let (from, to) = (state(f.chain, f.step.checked_sub(1)), state(f.chain, Some(f.step)));
        set(f.col, f64::from(u8::from(from == f.from && to == f.to)));
    }
    for &(l, col) in &cols.seen {
        let lane = (l + 1) as u8;
        set(col, f64::from(u8::from(r.maneuvers.iter().any(|m| m.lane == lane))));
    }
    // The evaluation's slacks are laid out `[sv * H + step]`.
    let at = |cell: Cell| cell.sv * problem.horizon + cell.step;
    for (cell, col) in cols.slacks.hysteresis.iter() {
        if let Some(col) = *col {
            set(col, e.hysteresis_slack[at(cell)]);
        }
    }
    for (cell, col) in cols.slacks.global.iter() {
        if let Some(col) = *col {
            set(col, e.global_slack[at(cell)]);
        }
    }
    x
}

/// Settling a layer by its LP relaxation and the small branch and bound over it is exact: on
/// the corpus, every layer gets the same optimal cost as with the MIP alone. With the root
/// relaxation only (a budget of 1 LP) some layers go on to the MIP, and the default budget
/// settles more of them, so every path is exercised.
#[test]
fn the_relaxation_first_gives_the_mips_optimum() {
    for continuous in [true, false] {
        let mut config = PlannerConfig::default();
        config.ego.continuous_accel = continuous;
        let mut direct_settings = config.solver.clone();
        direct_settings.relaxation_first = false;
        let mut root_settings = config.solver.clone();
        root_settings.branch_lps = 1;
        let mut tree = MilpBackend::new(&config.solver).unwrap();
        let mut root = MilpBackend::new(&root_settings).unwrap();
        let mut direct = MilpBackend::new(&direct_settings).unwrap();
        let (mut by_tree, mut by_root, mut layers) = (0, 0, 0);
        for class in paper_classes() {
            let mut generator = SituationGenerator::new(7 + u64::from(class.id));
            for _ in 0..6 {
                let s = generator.situation(&config, &class);
                let problem = prepare(&config, &s).problem;
                let keep = vec![vec![Action::KEEP; problem.horizon]];
                for mode in [Mode::Nominal, Mode::Relaxed] {
                    let b = direct.solve(&problem, mode, &keep).unwrap();
                    let cost = |o: &LayerOutcome| o.evaluation.as_ref().map(|e| e.cost);
                    for backend in [&mut tree, &mut root] {
                        let a = backend.solve(&problem, mode, &keep).unwrap();
                        match (cost(&a), cost(&b)) {
                            (Some(x), Some(y)) => assert!((x - y).abs() <= 1e-6 * (1.0 + y.abs()), "{x} vs {y}: {s:?}"),
                            (x, y) => assert_eq!(x, y, "{s:?}"),
                        }
                    }
                    by_tree += usize::from(tree.solve(&problem, mode, &keep).unwrap().settled_at_root);
                    by_root += usize::from(root.solve(&problem, mode, &keep).unwrap().settled_at_root);
                    layers += 1;
                }
            }
        }
        assert!(
            by_root > 0 && by_root < by_tree,
            "continuous {continuous}: {layers} layers, settled by the root {by_root}, by the tree {by_tree}"
        );
    }
}

/// `[solver.highs_options]` reach the branch and bound's LP instance as well as the MIP's:
/// with no simplex iteration allowed no relaxation settles a layer that needs one, and with
/// the options the MIP alone saw, the tree settled most of them.
#[test]
fn extra_highs_options_reach_the_tree_lps() {
    let config = PlannerConfig::default();
    let mut stopped = config.solver.clone();
    stopped.tree_lp = crate::config::LpSolver::Highs;
    stopped.highs_options.insert(
        "simplex_iteration_limit".into(),
        crate::config::HighsOptionValue::Int(0),
    );
    let mut free_settings = config.solver.clone();
    free_settings.tree_lp = crate::config::LpSolver::Highs;
    let mut free = MilpBackend::new(&free_settings).unwrap();
    let mut limited = MilpBackend::new(&stopped).unwrap();
    let (mut by_free, mut by_limited) = (0, 0);
    for class in paper_classes() {
        let mut generator = SituationGenerator::new(11 + u64::from(class.id));
        for _ in 0..3 {
            let s = generator.situation(&config, &class);
            let problem = prepare(&config, &s).problem;
            let Ok((model, _)) = build(&problem, Mode::Nominal) else {
                continue;
            };
            if model.num_rows() == 0 {
                continue; // settled by construction, no LP run
            }
            let keep = vec![vec![Action::KEEP; problem.horizon]];
            by_free += usize::from(free.solve(&problem, Mode::Nominal, &keep).unwrap().settled_at_root);
            by_limited += usize::from(limited.solve(&problem, Mode::Nominal, &keep).unwrap().settled_at_root);
        }
    }
    assert!(by_free > 10, "the tree settled only {by_free} layers");
    assert_eq!(by_limited, 0, "layers settled by LPs that could not iterate");
}

/// The dense simplex (steepest edge, bound flipping) reaches HiGHS's optimum on the
/// relaxations of the bench corpus, both layers, whatever their size: the tree prunes on
/// this bound, so a value above the true one would drop the optimum.
#[test]
fn dense_relaxations_agree_with_highs() {
    let config = PlannerConfig::default();
    let mut solved = 0;
    for class in paper_classes() {
        let mut generator = SituationGenerator::new(31 + u64::from(class.id));
        for _ in 0..4 {
            let s = generator.situation(&config, &class);
            let problem = prepare(&config, &s).problem;
            for mode in [Mode::Nominal, Mode::Relaxed] {
                let Ok((model, _)) = build(&problem, mode) else {
                    continue;
                };
                dense_relaxation_agrees_with_highs(&model);
                solved += 1;
            }
        }
    }
    assert!(solved > 100, "{solved} relaxations");
}

/// The dense simplex's verdict on `model`'s relaxation is HiGHS's: the same optimal
/// objective (relative 1e-7) at a point within the boxes and rows, or infeasible for both.
fn dense_relaxation_agrees_with_highs(model: &MipModel) {
    let lp = branch::dense_relaxation(model);
    let dense = lp.solve_with(dense_lp::Pricing::SteepestEdge).expect("dense simplex");
    let mut relaxed = model.clone();
    relaxed.integer.iter_mut().for_each(|i| *i = false);
    let highs = crate::highs_solver::with_thread_lp(|s| s.solve(&relaxed, None)).unwrap();
    match (dense, highs.status) {
        (dense_lp::LpOutcome::Optimal { x, objective }, MipStatus::Optimal) => {
            let h = highs.objective;
            assert!(
                (objective - h).abs() <= 1e-7 * (1.0 + h.abs()),
                "{objective} vs HiGHS {h}"
            );
            for (c, &v) in x.iter().enumerate() {
                let (lo, hi) = lp.bounds(c);
                assert!(v >= lo && v <= hi, "column {c} = {v} outside [{lo}, {hi}]");
            }
            for r in 0..lp.num_rows() {
                let ((lo, hi), a) = (lp.row_bounds(r), lp.activity(r, &x));
                assert!(a >= lo - 1e-9 && a <= hi + 1e-9, "row {r}: {a} outside [{lo}, {hi}]");
            }
        }
        (dense_lp::LpOutcome::Infeasible, MipStatus::Infeasible) => {}
        (d, h) => panic!("dense {d:?} vs HiGHS {h:?}"),
    }
}
