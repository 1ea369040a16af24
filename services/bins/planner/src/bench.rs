//! Solve a seeded corpus of situations for each traffic class of the paper's Table I with
//! both backends, time every decision, and check the MILP against the oracle.

use std::time::Instant;

use decision::corpus::{agree, paper_classes, SituationGenerator, TrafficClass};
use decision::{Backend, Decision, DecisionError, Planner, PlannerConfig, Situation};
use serde::Serialize;
use stats::{LayerCounts, Percentiles};

#[derive(Debug, Clone, Serialize)]
pub struct Agreement {
    pub checked: usize,
    pub agreed: usize,
    pub rate: f64,
    /// The first few disagreements, described.
    pub examples: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ClassReport {
    pub class: TrafficClass,
    pub milp: Percentiles,
    pub enumeration: Percentiles,
    pub agreement_rate: f64,
    pub layers: LayerCounts,
}

/// Decision times per backend, µs (exact, nearest rank).
#[derive(Debug, Clone, Serialize)]
pub struct Backends {
    pub milp: Percentiles,
    pub enumeration: Percentiles,
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

/// The share of `agreed` among `checked` (1 when nothing was checked).
fn rate(agreed: usize, checked: usize) -> f64 {
    if checked == 0 {
        1.0
    } else {
        agreed as f64 / checked as f64
    }
}

/// The MILP planner and the exact oracle (enumeration), both on `config`.
pub(crate) fn both_backends(config: &PlannerConfig) -> Result<(Planner, Planner), DecisionError> {
    let on = |backend| {
        let mut c = config.clone();
        c.solver.backend = backend;
        Planner::new(c)
    };
    Ok((on(Backend::Milp)?, on(Backend::Enumeration)?))
}

/// One decision, its wall time appended to `times` (µs).
pub(crate) fn timed_decision(
    planner: &mut Planner,
    situation: &Situation,
    times: &mut Vec<u64>,
) -> Result<Decision, DecisionError> {
    let started = Instant::now();
    let decision = planner.decide(situation);
    times.push(started.elapsed().as_micros() as u64);
    decision
}

/// Run the benchmark.
pub fn run(config: &PlannerConfig, per_class: usize, seed: u64) -> Result<BenchReport, DecisionError> {
    let (mut milp, mut oracle) = both_backends(config)?;
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
            let (a, b) = if k % 2 == 0 {
                let a = timed_decision(&mut milp, &situation, &mut t_milp)?;
                (a, timed_decision(&mut oracle, &situation, &mut t_oracle)?)
            } else {
                let b = timed_decision(&mut oracle, &situation, &mut t_oracle)?;
                (timed_decision(&mut milp, &situation, &mut t_milp)?, b)
            };
            layers.add(a.layer.into());
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
            milp: Percentiles::of_samples(&mut t_milp),
            enumeration: Percentiles::of_samples(&mut t_oracle),
            agreement_rate: rate(agreed, per_class),
            layers,
        });
    }
    agreement.rate = rate(agreement.agreed, agreement.checked);
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
            milp: Percentiles::of_samples(&mut all_milp),
            enumeration: Percentiles::of_samples(&mut all_oracle),
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
    fn small_bench_agrees_everywhere() {
        let r = run(&PlannerConfig::default(), 3, 5).unwrap();
        assert_eq!(r.situations, 54);
        assert_eq!(r.classes.len(), 18);
        assert_eq!(r.agreement.rate, 1.0, "{:?}", r.agreement.examples);
        assert_eq!(r.backends.milp.count, 54);
        assert_eq!(r.target_class.class.id, 18);
    }
}
