//! Decision time per backend on Table I traffic classes, and per horizon on the target class
//! (`cargo bench -p decision`).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use decision::corpus::{paper_classes, SituationGenerator};
use decision::{Backend, Planner, PlannerConfig};

fn decide(c: &mut Criterion) {
    let mut group = c.benchmark_group("decide");
    // Urban 2 lanes / 5 SVs, and the target class: highway, 4 lanes, 10 SVs.
    for class_id in [1u8, 18] {
        let class = paper_classes().into_iter().find(|c| c.id == class_id).unwrap();
        let config = PlannerConfig::default();
        let mut generator = SituationGenerator::new(42);
        let situations: Vec<_> = (0..64).map(|_| generator.situation(&config, &class)).collect();
        for backend in [Backend::Milp, Backend::Enumeration] {
            let mut config = config.clone();
            config.solver.backend = backend;
            let mut planner = Planner::new(config).unwrap();
            let mut k = 0;
            group.bench_function(BenchmarkId::new(backend.name(), format!("class{class_id}")), |b| {
                b.iter(|| {
                    k = (k + 1) % situations.len();
                    planner.decide(&situations[k]).unwrap()
                })
            });
        }
    }
    group.finish();
}

/// The target class (highway, 4 lanes, 10 SVs) at H = 3..=6, single actions. Enumeration
/// runs up to H = 5 (at H = 6 one decision takes about a second).
fn horizon(c: &mut Criterion) {
    let mut group = c.benchmark_group("horizon");
    group.sample_size(20);
    let class = paper_classes().into_iter().find(|c| c.id == 18).unwrap();
    for h in 3..=6usize {
        let mut config = PlannerConfig::default();
        config.timing.horizon = h;
        let mut generator = SituationGenerator::new(43);
        let situations: Vec<_> = (0..32).map(|_| generator.situation(&config, &class)).collect();
        for backend in [Backend::Milp, Backend::Enumeration] {
            if backend == Backend::Enumeration && h > 5 {
                continue;
            }
            let mut config = config.clone();
            config.solver.backend = backend;
            let mut planner = Planner::new(config).unwrap();
            let mut k = 0;
            group.bench_function(BenchmarkId::new(backend.name(), format!("H{h}")), |b| {
                b.iter(|| {
                    k = (k + 1) % situations.len();
                    planner.decide(&situations[k]).unwrap()
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, decide, horizon);
criterion_main!(benches);
