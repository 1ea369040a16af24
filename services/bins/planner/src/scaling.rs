//! How solve time grows with the horizon, the action set and the SV count: both backends on
//! the same seeded situations of the 4-lane highway class, with their agreement.

use decision::corpus::{agree, paper_classes, SituationGenerator, TrafficClass};
use decision::model::admissible_sequences;
use decision::{DecisionError, PlannerConfig};
use serde::Serialize;
use stats::Percentiles;

use crate::bench::{both_backends, timed_decision};

/// What to sweep.
#[derive(Debug, Clone, Serialize)]
pub struct ScalingSpec {
    pub horizons: Vec<usize>,
    /// `false`: single actions (lateral or longitudinal per step); `true`: combined (9).
    pub combined: Vec<bool>,
    pub svs: Vec<usize>,
    /// Situations per cell.
    pub per_cell: usize,
    pub seed: u64,
    /// Enumeration is skipped in cells with more action sequences than this (it grows as
    /// `5^H` or `9^H` and each sequence is an LP with the continuous input).
    pub max_sequences: usize,
}

/// One cell of the sweep.
#[derive(Debug, Clone, Serialize)]
pub struct ScalingCell {
    pub horizon: usize,
    pub combined: bool,
    pub svs: usize,
    /// Admissible action sequences from a middle lane.
    pub sequences: usize,
    /// The scenario tree's size: kept branches per SV in the perception window, and the
    /// MILP's rows (of the last layer solved), means over the cell's situations.
    pub branches_per_sv: f64,
    pub rows: f64,
    pub milp: Percentiles,
    /// `None` where the enumeration was skipped.
    pub enumeration: Option<Percentiles>,
    /// Situations on which both backends agreed, of those compared.
    pub agreed: usize,
    pub compared: usize,
    /// The first disagreements, described.
    pub disagreements: Vec<String>,
}

impl ScalingCell {
    /// Enumeration p50 over MILP p50 (`None` without enumeration).
    pub fn speedup_p50(&self) -> Option<f64> {
        self.enumeration
            .as_ref()
            .map(|e| e.p50_us as f64 / (self.milp.p50_us.max(1)) as f64)
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ScalingReport {
    pub spec: ScalingSpec,
    pub cells: Vec<ScalingCell>,
}

/// Table I row 18 (4 lanes, highway speeds) with `svs` SVs.
fn highway_class(svs: usize) -> TrafficClass {
    let row18 = paper_classes()
        .into_iter()
        .find(|c| c.id == 18)
        .expect("Table I has row 18");
    TrafficClass { svs, ..row18 }
}

/// Run the sweep with `base` for everything but the horizon and the action set.
pub fn run(base: &PlannerConfig, spec: &ScalingSpec) -> Result<ScalingReport, DecisionError> {
    let mut cells = Vec::new();
    for &horizon in &spec.horizons {
        for &combined in &spec.combined {
            let mut config = base.clone();
            config.timing.horizon = horizon;
            config.ego.combined_actions = combined;
            let sequences = admissible_sequences(decision::Maneuver { lane: 2, beta: 0 }, 4, horizon, combined).len();
            let with_oracle = sequences <= spec.max_sequences;
            let (mut milp, mut oracle) = both_backends(&config)?;
            for &svs in &spec.svs {
                let class = highway_class(svs);
                let mut generator =
                    SituationGenerator::new(spec.seed ^ ((horizon as u64) << 40) ^ ((svs as u64) << 32));
                let (mut t_milp, mut t_oracle) = (Vec::new(), Vec::new());
                let mut cell = ScalingCell {
                    horizon,
                    combined,
                    svs,
                    sequences,
                    branches_per_sv: 0.0,
                    rows: 0.0,
                    milp: Percentiles::default(),
                    enumeration: None,
                    agreed: 0,
                    compared: 0,
                    disagreements: Vec::new(),
                };
                for k in 0..spec.per_cell {
                    let s = generator.situation(&config, &class);
                    let a = timed_decision(&mut milp, &s, &mut t_milp)?;
                    let n = spec.per_cell as f64;
                    cell.branches_per_sv += a.stats.branches as f64 / a.stats.svs_considered.max(1) as f64 / n;
                    cell.rows += a.stats.rows as f64 / n;
                    if with_oracle {
                        let b = timed_decision(&mut oracle, &s, &mut t_oracle)?;
                        cell.compared += 1;
                        match agree(&config, &s, &a, &b) {
                            Ok(()) => cell.agreed += 1,
                            Err(why) if cell.disagreements.len() < 3 => {
                                cell.disagreements.push(format!("case {k}: {why}"))
                            }
                            Err(_) => {}
                        }
                    }
                }
                cell.milp = Percentiles::of_samples(&mut t_milp);
                cell.enumeration = with_oracle.then(|| Percentiles::of_samples(&mut t_oracle));
                cells.push(cell);
            }
        }
    }
    Ok(ScalingReport {
        spec: spec.clone(),
        cells,
    })
}

/// The sweep as a text table, ms.
pub fn render(report: &ScalingReport) -> String {
    let ms = |us: u64| us as f64 / 1000.0;
    let mut out = String::from(
        "   H  actions   SVs  sequences  branches/SV   rows  MILP p50 / p99 / max (ms)    enumeration p50 / p99 / max (ms)  p50 ratio  agreement\n",
    );
    for c in &report.cells {
        let m = &c.milp;
        let e = c.enumeration.as_ref().map_or("-".to_string(), |e| {
            format!("{:8.2} / {:8.2} / {:8.2}", ms(e.p50_us), ms(e.p99_us), ms(e.max_us))
        });
        let ratio = c.speedup_p50().map_or("-".to_string(), |r| format!("{r:.1}x"));
        let agreement = if c.compared == 0 {
            "-".to_string()
        } else {
            format!("{} / {}", c.agreed, c.compared)
        };
        out.push_str(&format!(
            "{:>4}  {:<8} {:>4}  {:>9}  {:>11.2}  {:>5.0}  {:7.2} / {:7.2} / {:7.2}    {:>32}  {:>9}  {}\n",
            c.horizon,
            if c.combined { "combined" } else { "single" },
            c.svs,
            c.sequences,
            c.branches_per_sv,
            c.rows,
            ms(m.p50_us),
            ms(m.p99_us),
            ms(m.max_us),
            e,
            ratio,
            agreement
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_sweep_compares_both_backends_and_skips_what_is_too_large() {
        let spec = ScalingSpec {
            horizons: vec![2, 3],
            combined: vec![false, true],
            svs: vec![4],
            per_cell: 3,
            seed: 9,
            max_sequences: 200,
        };
        let r = run(&PlannerConfig::default(), &spec).unwrap();
        assert_eq!(r.cells.len(), 4);
        for c in &r.cells {
            assert_eq!(c.milp.count, 3);
            let expect_oracle = c.sequences <= 200;
            assert_eq!(c.enumeration.is_some(), expect_oracle, "{c:?}");
            if expect_oracle {
                assert_eq!((c.agreed, c.compared), (3, 3), "{:?}", c.disagreements);
            }
        }
        // Combined actions at H = 3 are 9^3 sequences (fewer at a road edge): skipped.
        assert!(r.cells.iter().any(|c| c.enumeration.is_none()));
        let text = render(&r);
        assert_eq!(text.lines().count(), 5, "{text}");
    }
}
