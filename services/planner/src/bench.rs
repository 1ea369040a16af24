//! Solve a seeded corpus of situations for each traffic class of the paper's Table I with
//! both backends, time every decision, and check the MILP against the oracle.

use std::time::Instant;

use decision::corpus::{agree, paper_classes, SituationGenerator, TrafficClass};
use decision::{Backend, DecisionError, Layer, Planner, PlannerConfig};
use serde::Serialize;

/// Percentiles of one backend's decision times, microseconds.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    pub solved: usize,
    pub mean_us: f64,
    pub p50_us: u64,
    pub p99_us: u64,
    pub max_us: u64,
}

impl Timing {
    /// Exact percentiles (nearest rank) of the samples.
    pub fn of(samples: &[u64]) -> Timing {
        let mut s = samples.to_vec();
        s.sort_unstable();
        let rank = |q: f64| -> u64 {
            if s.is_empty() {
                return 0;
            }
            let idx = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1;
            s[idx]
        };
        Timing {
            solved: s.len(),
            mean_us: if s.is_empty() {
                0.0
            } else {
                s.iter().sum::<u64>() as f64 / s.len() as f64
            },
            p50_us: rank(0.50),
            p99_us: rank(0.99),
            max_us: s.last().copied().unwrap_or(0),
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct Agreement {
    pub checked: usize,
    pub agreed: usize,
    pub rate: f64,
    /// The first few disagreements, described.
    pub examples: Vec<String>,
}

#[derive(Debug, Clone, Serialize, Default)]
pub struct LayerCounts {
    pub nominal: usize,
    pub global_relaxation: usize,
    pub fallback: usize,
}

#[derive(Debug, Clone, Serialize)]
pub struct ClassReport {
    pub class: TrafficClass,
    pub milp: Timing,
    pub enumeration: Timing,
    pub agreement_rate: f64,
    pub layers: LayerCounts,
}

#[derive(Debug, Clone, Serialize)]
pub struct Backends {
    pub milp: Timing,
    pub enumeration: Timing,
}

#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    pub seed: u64,
    pub per_class: usize,
    pub situations: usize,
    pub backends: Backends,
    pub agreement: Agreement,
    /// The class the targets are set on: 4 lanes, 10 SVs, highway (Table I row 18).
    pub target_class: ClassReport,
    pub classes: Vec<ClassReport>,
}

/// Run the benchmark.
pub fn run(config: &PlannerConfig, per_class: usize, seed: u64) -> Result<BenchReport, DecisionError> {
    let mut milp_config = config.clone();
    milp_config.solver.backend = Backend::Milp;
    let mut oracle_config = config.clone();
    oracle_config.solver.backend = Backend::Enumeration;
    let mut milp = Planner::new(milp_config)?;
    let mut oracle = Planner::new(oracle_config)?;
    let (mut all_milp, mut all_oracle) = (Vec::new(), Vec::new());
    let mut agreement = Agreement {
        checked: 0,
        agreed: 0,
        rate: 0.0,
        examples: Vec::new(),
    };
    let mut classes = Vec::new();
    for class in paper_classes() {
        let mut generator = SituationGenerator::new(seed ^ (u64::from(class.id) << 32));
        let (mut t_milp, mut t_oracle) = (Vec::with_capacity(per_class), Vec::with_capacity(per_class));
        let mut layers = LayerCounts::default();
        let mut agreed = 0;
        for k in 0..per_class {
            let situation = generator.situation(config, &class);
            // Alternate the order so neither backend always runs on a warm cache.
            let timed = |planner: &mut Planner, times: &mut Vec<u64>| {
                let started = Instant::now();
                let decision = planner.decide(&situation);
                times.push(started.elapsed().as_micros() as u64);
                decision
            };
            let (a, b) = if k % 2 == 0 {
                let a = timed(&mut milp, &mut t_milp)?;
                (a, timed(&mut oracle, &mut t_oracle)?)
            } else {
                let b = timed(&mut oracle, &mut t_oracle)?;
                (timed(&mut milp, &mut t_milp)?, b)
            };
            match a.layer {
                Layer::Nominal => layers.nominal += 1,
                Layer::GlobalRelaxation => layers.global_relaxation += 1,
                Layer::Fallback => layers.fallback += 1,
            }
            match agree(config, &situation, &a, &b) {
                Ok(()) => agreed += 1,
                Err(why) if agreement.examples.len() < 5 => {
                    agreement.examples.push(format!("class {} case {k}: {why}", class.id));
                }
                Err(_) => {}
            }
        }
        agreement.checked += per_class;
        agreement.agreed += agreed;
        all_milp.extend_from_slice(&t_milp);
        all_oracle.extend_from_slice(&t_oracle);
        classes.push(ClassReport {
            class,
            milp: Timing::of(&t_milp),
            enumeration: Timing::of(&t_oracle),
            agreement_rate: if per_class == 0 {
                1.0
            } else {
                agreed as f64 / per_class as f64
            },
            layers,
        });
    }
    agreement.rate = if agreement.checked == 0 {
        1.0
    } else {
        agreement.agreed as f64 / agreement.checked as f64
    };
    let target_class = classes
        .iter()
        .find(|c| c.class.lanes == 4 && c.class.svs == 10 && c.class.is_highway())
        .cloned()
        .expect("Table I has a 4-lane, 10-SV highway class");
    Ok(BenchReport {
        seed,
        per_class,
        situations: agreement.checked,
        backends: Backends {
            milp: Timing::of(&all_milp),
            enumeration: Timing::of(&all_oracle),
        },
        agreement,
        target_class,
        classes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let samples: Vec<u64> = (1..=100).rev().collect();
        let t = Timing::of(&samples);
        assert_eq!((t.p50_us, t.p99_us, t.max_us, t.solved), (50, 99, 100, 100));
        assert!((t.mean_us - 50.5).abs() < 1e-12);
        assert_eq!(Timing::of(&[]).max_us, 0);
    }

    #[test]
    fn small_bench_agrees_everywhere() {
        let r = run(&PlannerConfig::default(), 3, 5).unwrap();
        assert_eq!(r.situations, 54);
        assert_eq!(r.classes.len(), 18);
        assert_eq!(r.agreement.rate, 1.0, "{:?}", r.agreement.examples);
        assert_eq!(r.backends.milp.solved, 54);
        assert_eq!(r.target_class.class.id, 18);
    }
}
