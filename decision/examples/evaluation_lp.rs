//! Time per call of the exact evaluation's LP, HiGHS against the dense simplex, on the same
//! instances: every admissible sequence of seeded corpus situations (all 18 classes), both
//! modes. Prints p50 / p99 / mean per solver and their ratios.
//!
//! `cargo run --release -p decision --example evaluation_lp -- [--horizon H] [--combined]
//! [--situations N]` (N per class, default 6).
use std::time::Instant;

use decision::accel_lp::{by_dense, by_highs};
use decision::corpus::{paper_classes, SituationGenerator};
use decision::prepare;
use decision::rollout;
use decision::PlannerConfig;
use decision::{requirements, Mode};

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |name: &str, default: usize| {
        args.iter()
            .position(|a| a == name)
            .map_or(default, |i| args[i + 1].parse().expect("a number"))
    };
    let mut config = PlannerConfig::default();
    config.timing.horizon = value("--horizon", config.timing.horizon);
    config.ego.combined_actions = args.iter().any(|a| a == "--combined");
    let situations = value("--situations", 6);
    let mut instances = Vec::new();
    for class in paper_classes() {
        let mut generator = SituationGenerator::new(2026 + u64::from(class.id));
        for _ in 0..situations {
            let problem = prepare(&config, &generator.situation(&config, &class)).problem;
            let sequences = problem.admissible_sequences();
            let stride = (sequences.len() / 200).max(1);
            for actions in sequences.iter().step_by(stride) {
                if let Some(r) = rollout(&problem.kin, problem.lanes, &problem.ego, actions) {
                    let rows = requirements(&problem, &r);
                    for mode in [Mode::Nominal, Mode::Relaxed] {
                        instances.push((problem.clone(), r.clone(), rows.clone(), mode));
                    }
                }
            }
        }
    }
    let (mut highs, mut dense) = (Vec::new(), Vec::new());
    let mut infeasible = 0;
    for pass in 0..2 {
        for (problem, r, rows, mode) in &instances {
            let start = Instant::now();
            let a = by_highs(problem, r, rows, *mode);
            let t_highs = start.elapsed().as_secs_f64() * 1e6;
            let start = Instant::now();
            let b = by_dense(problem, r, rows, *mode).expect("a verdict");
            let t_dense = start.elapsed().as_secs_f64() * 1e6;
            assert_eq!(a.is_some(), b.is_some());
            // The first pass warms caches and HiGHS's instance.
            if pass == 1 {
                highs.push(t_highs);
                dense.push(t_dense);
                infeasible += usize::from(a.is_none());
            }
        }
    }
    println!(
        "H = {}, combined {}: {} LPs ({infeasible} infeasible)",
        config.timing.horizon,
        config.ego.combined_actions,
        instances.len()
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (mean_h, mean_d) = (mean(&highs), mean(&dense));
    highs.sort_by(f64::total_cmp);
    dense.sort_by(f64::total_cmp);
    println!("          p50 us    p99 us   mean us");
    for (name, v, m) in [("highs", &highs, mean_h), ("dense", &dense, mean_d)] {
        println!(
            "{name:6} {:9.2} {:9.2} {:9.2}",
            percentile(v, 0.5),
            percentile(v, 0.99),
            m
        );
    }
    println!(
        "ratio  {:9.1} {:9.1} {:9.1}",
        percentile(&highs, 0.5) / percentile(&dense, 0.5),
        percentile(&highs, 0.99) / percentile(&dense, 0.99),
        mean_h / mean_d
    );
}
