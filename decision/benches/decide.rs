//! Decision time per backend on Table I traffic classes (`cargo bench -p decision`).

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

criterion_group!(benches, decide);
criterion_main!(benches);
