//! Paired comparison of two campaign runs: every headline figure of one driver, candidate
//! minus baseline, with a bootstrap interval over the trials.
//!
//! Both runs must have the same seed and configurations, so that trial `k` of configuration
//! `c` met the same traffic in both: the difference is then paired, and the interval is far
//! narrower than two runs' separate spreads would suggest. Each resample draws every
//! configuration's trials with replacement within that configuration (the campaign fixes
//! how many trials each has), the same draw for both runs, and recomputes each figure with
//! [`aggregate`], the campaign report's own definition. The draws come from a seeded
//! stream: the same inputs and seed give the same intervals.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

use crate::campaign::{aggregate, DriverKind, GroupResult, TrialOutcome, TrialRecord};
use crate::error::{Result, SimClientError};

/// Which direction of a figure is the better one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Better {
    /// More is better (speed, time to collision).
    Higher,
    /// Less is better (switches, hard brakes, time at short headway).
    Lower,
    /// Neither (lane changes: a means, not a goal).
    Neither,
}

/// A campaign figure `compare` reports.
pub struct Figure {
    /// Name, with its unit.
    pub name: &'static str,
    /// Its better direction.
    pub better: Better,
    /// Its value for a group (`None`: undefined, e.g. no TTC at all).
    pub value: fn(&GroupResult) -> Option<f64>,
}

/// The figures compared, in report order.
pub const FIGURES: &[Figure] = &[
    Figure {
        name: "mean speed (m/s)",
        better: Better::Higher,
        value: |g| Some(g.mean_speed_mps),
    },
    Figure {
        name: "beta switches/min",
        better: Better::Lower,
        value: |g| Some(g.beta_switches_per_min),
    },
    Figure {
        name: "lane changes/min",
        better: Better::Neither,
        value: |g| Some(g.lane_changes_per_min),
    },
    Figure {
        name: "hard brakes/h",
        better: Better::Lower,
        value: |g| Some(g.safety.hard_braking_per_hour),
    },
    Figure {
        name: "min TTC p5 (s)",
        better: Better::Higher,
        value: |g| g.safety.min_ttc_p5_s,
    },
    Figure {
        name: "min TTC p50 (s)",
        better: Better::Higher,
        value: |g| g.safety.min_ttc_p50_s,
    },
    Figure {
        name: "TTC < 3 s (%)",
        better: Better::Lower,
        value: |g| Some(100.0 * g.safety.ttc_below_3s_share),
    },
    Figure {
        name: "headway < 1 s (%)",
        better: Better::Lower,
        value: |g| Some(100.0 * g.safety.headway_below_1s_share),
    },
    Figure {
        name: "collision rate (%)",
        better: Better::Lower,
        value: |g| Some(100.0 * g.collision_rate),
    },
    Figure {
        name: "NOR (%)",
        better: Better::Higher,
        value: |g| g.nor.map(|v| 100.0 * v),
    },
    Figure {
        name: "NOR, plain MPC (%)",
        better: Better::Higher,
        value: |g| g.plain_nor.map(|v| 100.0 * v),
    },
    Figure {
        name: "FBR (%)",
        better: Better::Lower,
        value: |g| g.fbr.map(|v| 100.0 * v),
    },
];

/// What the interval says about a difference.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The interval lies wholly on the better side of 0.
    Better,
    /// The interval lies wholly on the worse side of 0.
    Worse,
    /// The interval lies wholly above or below 0 for a figure without a better direction.
    Differs,
    /// The interval includes 0.
    NoDifference,
    /// The figure is undefined in one run, or in too many resamples.
    Undefined,
}

/// One figure, both runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FigureComparison {
    /// Figure name.
    pub name: &'static str,
    /// Baseline run.
    pub baseline: Option<f64>,
    /// Candidate run.
    pub candidate: Option<f64>,
    /// `candidate - baseline`.
    pub difference: Option<f64>,
    /// The bootstrap interval of the difference (central, at the comparison's confidence).
    pub interval: Option<(f64, f64)>,
    /// What the interval says.
    pub verdict: Verdict,
}

/// A trial of both runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairedTrial {
    /// Configuration id.
    pub config_id: u32,
    /// Trial index.
    pub trial: u32,
    /// The trial's scenario seed.
    pub seed: u64,
    /// The baseline's least TTC in the trial (s; `None`: never closing in).
    pub baseline_min_ttc_s: Option<f64>,
    /// The candidate's.
    pub candidate_min_ttc_s: Option<f64>,
}

/// The comparison of two runs for one driver.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// The baseline run's driver.
    pub driver: DriverKind,
    /// The candidate run's driver.
    pub candidate_driver: DriverKind,
    /// Paired trials.
    pub trials: usize,
    /// Bootstrap resamples.
    pub resamples: usize,
    /// Confidence of the intervals.
    pub confidence: f64,
    /// Seed of the resampling stream.
    pub seed: u64,
    /// Every figure of [`FIGURES`], in that order.
    pub figures: Vec<FigureComparison>,
    /// The paired trials, in (configuration, trial) order.
    #[serde(skip)]
    pub paired: Vec<PairedTrial>,
}

impl Comparison {
    /// The `n` trials with the candidate's shortest least TTC (the ones its TTC p5 comes from).
    pub fn lowest_candidate_ttc(&self, n: usize) -> Vec<&PairedTrial> {
        let mut v: Vec<&PairedTrial> = self.paired.iter().collect();
        let key = |t: &PairedTrial| t.candidate_min_ttc_s.unwrap_or(f64::INFINITY);
        v.sort_by(|a, b| {
            key(a)
                .total_cmp(&key(b))
                .then((a.config_id, a.trial).cmp(&(b.config_id, b.trial)))
        });
        v.truncate(n);
        v
    }
}

/// Reads trials.jsonl (a path to it, or a campaign output directory holding
/// `campaign/trials.jsonl`).
pub fn read_trials(path: &Path) -> Result<Vec<TrialRecord>> {
    let file = if path.is_dir() {
        path.join("campaign").join(crate::campaign_report::TRIALS_FILE)
    } else {
        path.to_path_buf()
    };
    let text = std::fs::read_to_string(&file).map_err(|e| SimClientError::io(&file, e))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l)
                .map_err(|e| SimClientError::Config(format!("{} line {}: {e}", file.display(), i + 1)))
        })
        .collect()
}

/// The seeded stream the resamples draw from (SplitMix64).
struct Draws(u64);

impl Draws {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (multiply-shift; the bias is below 2^-40 for any campaign's `n`).
    fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.next()) * n as u128) >> 64) as usize
    }
}

fn outcome(r: &TrialRecord) -> TrialOutcome {
    TrialOutcome {
        config_id: r.config_id,
        trial: r.trial,
        driver: r.driver,
        metrics: r.metrics.clone(),
        solve_us: Vec::new(),
        hard_braking: Vec::new(),
    }
}

/// Two runs' outcomes of one driver, aligned by (configuration, trial).
struct Paired {
    baseline: Vec<TrialOutcome>,
    candidate: Vec<TrialOutcome>,
    seeds: Vec<u64>,
    dt: f64,
}

/// The paired trials (the baseline's of `drivers.0`, the candidate's of `drivers.1`), or a
/// typed error when the runs did not run the same trials of the same traffic on the same seeds.
fn pair(baseline: &[TrialRecord], candidate: &[TrialRecord], drivers: (DriverKind, DriverKind)) -> Result<Paired> {
    let index = |runs: &[TrialRecord], driver: DriverKind, which: &str| -> Result<BTreeMap<(u32, u32), TrialRecord>> {
        let mut m = BTreeMap::new();
        for r in runs.iter().filter(|r| r.driver == driver) {
            if m.insert((r.config_id, r.trial), r.clone()).is_some() {
                return Err(SimClientError::Config(format!(
                    "{which}: configuration {} trial {} appears twice",
                    r.config_id, r.trial
                )));
            }
        }
        if m.is_empty() {
            return Err(SimClientError::Config(format!(
                "{which}: no trial of {}",
                driver.name()
            )));
        }
        Ok(m)
    };
    let (b, c) = (
        index(baseline, drivers.0, "baseline")?,
        index(candidate, drivers.1, "candidate")?,
    );
    if b.len() != c.len() || b.keys().ne(c.keys()) {
        return Err(SimClientError::Config(format!(
            "the runs have different trials ({} and {}): compare runs of the same configurations",
            b.len(),
            c.len()
        )));
    }
    let mut dt = None;
    let (mut bo, mut co, mut seeds) = (Vec::new(), Vec::new(), Vec::new());
    for (key, rb) in &b {
        let rc = &c[key];
        if rb.seed != rc.seed {
            return Err(SimClientError::Config(format!(
                "configuration {} trial {} ran on different seeds: compare runs of the same campaign seed",
                key.0, key.1
            )));
        }
        if rb.sv != rc.sv {
            return Err(SimClientError::Config(format!(
                "configuration {}: the SVs drove otherwise in the two runs (keep probability {} / {}, random lane changes {} / {}, slowdown {} / {} m/s^2): compare runs of the same --sv-keep-long, --sv-lane-change and --sv-slowdown-decel",
                key.0,
                rb.sv.p_keep_long,
                rc.sv.p_keep_long,
                rb.sv.p_random_lane_change,
                rc.sv.p_random_lane_change,
                rb.sv.gentle_decel,
                rc.sv.gentle_decel
            )));
        }
        if rb.traffic != rc.traffic || rb.duration_s != rc.duration_s {
            return Err(SimClientError::Config(format!(
                "configuration {} has other traffic or another duration in the two runs: compare runs of the same configurations",
                key.0
            )));
        }
        if rb.dt_s != rc.dt_s || dt.is_some_and(|d| d != rb.dt_s) {
            return Err(SimClientError::Config("the runs have different simulator steps".into()));
        }
        dt = Some(rb.dt_s);
        bo.push(outcome(rb));
        co.push(outcome(rc));
        seeds.push(rb.seed);
    }
    Ok(Paired {
        baseline: bo,
        candidate: co,
        seeds,
        dt: dt.unwrap_or_default(),
    })
}

fn verdict(better: Better, lo: f64, hi: f64) -> Verdict {
    let above = lo > 0.0;
    let below = hi < 0.0;
    match (better, above, below) {
        (_, false, false) => Verdict::NoDifference,
        (Better::Neither, _, _) => Verdict::Differs,
        (Better::Higher, true, _) | (Better::Lower, _, true) => Verdict::Better,
        _ => Verdict::Worse,
    }
}

/// Compares two runs' drivers (`drivers.0` in the baseline run, `drivers.1` in the candidate
/// run; the same driver of two runs, or two drivers of one run): each figure's difference
/// with a central bootstrap interval at `confidence` from `resamples` stratified resamples of
/// the paired trials.
pub fn compare(
    baseline: &[TrialRecord],
    candidate: &[TrialRecord],
    drivers: (DriverKind, DriverKind),
    resamples: usize,
    confidence: f64,
    seed: u64,
) -> Result<Comparison> {
    if resamples == 0 || !(confidence > 0.0 && confidence < 1.0) {
        return Err(SimClientError::Config(
            "resamples must be positive and the confidence within (0, 1)".into(),
        ));
    }
    let Paired {
        baseline: bo,
        candidate: co,
        seeds,
        dt,
    } = pair(baseline, candidate, drivers)?;
    let (gb, gc) = (
        aggregate(None, drivers.0, bo.iter(), dt),
        aggregate(None, drivers.1, co.iter(), dt),
    );
    let mut strata: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (i, o) in bo.iter().enumerate() {
        strata.entry(o.config_id).or_default().push(i);
    }
    let mut draws = Draws(seed);
    let mut diffs: Vec<Vec<f64>> = vec![Vec::with_capacity(resamples); FIGURES.len()];
    let mut drawn = Vec::with_capacity(bo.len());
    for _ in 0..resamples {
        drawn.clear();
        for members in strata.values() {
            drawn.extend((0..members.len()).map(|_| members[draws.below(members.len())]));
        }
        let rb = aggregate(None, drivers.0, drawn.iter().map(|&i| &bo[i]), dt);
        let rc = aggregate(None, drivers.1, drawn.iter().map(|&i| &co[i]), dt);
        for (f, d) in FIGURES.iter().zip(diffs.iter_mut()) {
            if let (Some(x), Some(y)) = ((f.value)(&rb), (f.value)(&rc)) {
                d.push(y - x);
            }
        }
    }
    let tail = (1.0 - confidence) / 2.0;
    let figures = FIGURES
        .iter()
        .zip(diffs.iter_mut())
        .map(|(f, d)| {
            let (b, c) = ((f.value)(&gb), (f.value)(&gc));
            let difference = b.zip(c).map(|(b, c)| c - b);
            // An interval from a few defined resamples would say more than they do.
            let interval = (difference.is_some() && d.len() * 20 >= resamples * 19).then(|| {
                d.sort_by(f64::total_cmp);
                // As many resamples below the interval as above it.
                let k = ((tail * d.len() as f64) + 1e-9).floor() as usize;
                (d[k], d[d.len() - 1 - k])
            });
            FigureComparison {
                name: f.name,
                baseline: b,
                candidate: c,
                difference,
                interval,
                verdict: interval.map_or(Verdict::Undefined, |(lo, hi)| verdict(f.better, lo, hi)),
            }
        })
        .collect();
    let paired = bo
        .iter()
        .zip(&co)
        .zip(seeds)
        .map(|((b, c), seed)| PairedTrial {
            config_id: b.config_id,
            trial: b.trial,
            seed,
            baseline_min_ttc_s: b.metrics.safety.min_ttc_s,
            candidate_min_ttc_s: c.metrics.safety.min_ttc_s,
        })
        .collect();
    Ok(Comparison {
        driver: drivers.0,
        candidate_driver: drivers.1,
        trials: bo.len(),
        resamples,
        confidence,
        seed,
        figures,
        paired,
    })
}

/// The comparison as a text table, one figure per line.
pub fn comparison_table(c: &Comparison) -> String {
    use std::fmt::Write as _;
    let cell = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    let drivers = if c.driver == c.candidate_driver {
        c.driver.name().to_string()
    } else {
        format!("{} against {}", c.candidate_driver.name(), c.driver.name())
    };
    let mut out = format!(
        "{}: {} paired trials, {} resamples, {:.0} % intervals (seed {})\n{:<20} {:>10} {:>10} {:>10}  {:<22} {}\n",
        drivers,
        c.trials,
        c.resamples,
        100.0 * c.confidence,
        c.seed,
        "figure",
        "baseline",
        "candidate",
        "diff",
        "interval",
        "verdict"
    );
    for f in &c.figures {
        let interval = f
            .interval
            .map_or("-".to_string(), |(lo, hi)| format!("[{lo:+.3}, {hi:+.3}]"));
        let verdict = match f.verdict {
            Verdict::Better => "better",
            Verdict::Worse => "worse",
            Verdict::Differs => "differs",
            Verdict::NoDifference => "no difference",
            Verdict::Undefined => "undefined",
        };
        let diff = f.difference.map_or("-".to_string(), |v| format!("{v:+.3}"));
        let _ = writeln!(
            out,
            "{:<20} {:>10} {:>10} {:>10}  {:<22} {}",
            f.name,
            cell(f.baseline),
            cell(f.candidate),
            diff,
            interval,
            verdict
        );
    }
    out
}

#[cfg(test)]
#[path = "campaign_compare_tests.rs"]
mod tests;
