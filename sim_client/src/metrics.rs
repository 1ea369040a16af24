//! Per-episode metrics and their aggregation (pure).

use serde::{Deserialize, Serialize};

use crate::episode::Episode;
use crate::safety::{EgoCollisionKind, SafetySummary};

/// Decisions counted by the layer that produced them (the shared tally; rejections stay 0
/// in an episode, which stops at one).
pub use stats::LayerCounts;

/// Collisions by who caused them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CollisionSplit {
    /// The ego rear-ended a vehicle ahead in its lane, or changed lanes into a vehicle.
    pub ego_at_fault: u64,
    /// The ego kept its lane and was hit from behind or cut into.
    pub ego_hit_in_lane: u64,
    /// First contacts between two SVs (until the episode stopped).
    pub sv_sv: u64,
}

impl CollisionSplit {
    /// Ego collisions, both kinds.
    pub fn ego_total(&self) -> u64 {
        self.ego_at_fault + self.ego_hit_in_lane
    }

    /// Sum of two tallies.
    pub fn merge(&mut self, other: &CollisionSplit) {
        self.ego_at_fault += other.ego_at_fault;
        self.ego_hit_in_lane += other.ego_hit_in_lane;
        self.sv_sv += other.sv_sv;
    }
}

/// Nominal decisions by where they stand against the plain MPC (no violation allowance, band
/// slack within `d_HS`; [`decision::classify_nominal`]): what compares with the paper's NOR.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NominalSplit {
    /// The chosen plan satisfies the plain MPC.
    pub plain: u64,
    /// The chosen plan uses a relaxation, but the plain MPC has a plan too.
    pub relaxed_by_choice: u64,
    /// Only the violation allowance makes the state nominal.
    pub needed_allowance: u64,
    /// Only the soft band makes the state nominal.
    pub needed_soft_band: u64,
    /// Either relaxation does, the plain MPC does not.
    pub needed_either: u64,
}

impl NominalSplit {
    /// Counts one class.
    pub fn add(&mut self, class: decision::NominalClass) {
        use decision::NominalClass as C;
        *match class {
            C::Plain => &mut self.plain,
            C::RelaxedByChoice => &mut self.relaxed_by_choice,
            C::NeededAllowance => &mut self.needed_allowance,
            C::NeededSoftBand => &mut self.needed_soft_band,
            C::NeededEither => &mut self.needed_either,
        } += 1;
    }

    /// Sum of two tallies.
    pub fn merge(&mut self, other: &NominalSplit) {
        self.plain += other.plain;
        self.relaxed_by_choice += other.relaxed_by_choice;
        self.needed_allowance += other.needed_allowance;
        self.needed_soft_band += other.needed_soft_band;
        self.needed_either += other.needed_either;
    }

    /// Decisions the plain MPC would make nominally.
    pub fn plain_feasible(&self) -> u64 {
        self.plain + self.relaxed_by_choice
    }

    /// Decisions classified.
    pub fn total(&self) -> u64 {
        self.plain_feasible() + self.needed_allowance + self.needed_soft_band + self.needed_either
    }
}

/// Reproducible metrics of one episode (no wall-clock quantity).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeMetrics {
    /// Decision instants.
    pub decisions: u64,
    /// Planner decisions by layer (all zero for the IDM + MOBIL ego).
    pub decisions_by_layer: LayerCounts,
    /// The nominal decisions against the plain MPC (all zero unless audited).
    #[serde(default)]
    pub nominal_split: NominalSplit,
    /// 1 when the ego collided (the episode stopped there), else 0.
    pub collisions: u32,
    /// Time of the collision (s).
    pub collision_time_s: Option<f64>,
    /// The vehicle the ego hit.
    pub collision_with: Option<u32>,
    /// Ego collisions by cause, and SV-SV contacts.
    pub collision_split: CollisionSplit,
    /// Changes of the commanded target lane (the first decision compares with the initial lane).
    pub lane_changes: u32,
    /// Changes of the commanded beta between consecutive decisions.
    pub beta_switches: u32,
    /// Time spent with at least one SV in corrective mode (s).
    pub corrective_time_s: f64,
    /// Mean ego speed over all low-level steps (m/s).
    pub mean_speed_mps: f64,
    /// Simulated time (s).
    pub simulated_s: f64,
    /// Surrogate safety measures of the ego, step by step.
    pub safety: SafetySummary,
}

/// Rounds to 1e-9 so that sums of periods print cleanly and identically.
pub(crate) fn clean(x: f64) -> f64 {
    (x * 1e9).round() / 1e9
}

impl EpisodeMetrics {
    /// Computes the metrics of an episode.
    pub fn from_episode(e: &Episode) -> Self {
        let mut by_layer = LayerCounts::default();
        let mut nominal_split = NominalSplit::default();
        let mut lane_changes = 0;
        let mut beta_switches = 0;
        let mut corrective = 0u64;
        let mut last_lane = e.initial_lane;
        let mut last_beta: Option<i8> = None;
        for d in &e.decisions {
            if let Some(layer) = d.layer {
                by_layer.add(layer);
            }
            if let Some(class) = d.nominal_class {
                nominal_split.add(class);
            }
            if d.target_lane != last_lane {
                lane_changes += 1;
                last_lane = d.target_lane;
            }
            if last_beta.is_some_and(|b| b != d.beta) {
                beta_switches += 1;
            }
            last_beta = Some(d.beta);
            if d.corrective_svs > 0 {
                corrective += 1;
            }
        }
        let kind = e.collision.map(|c| c.kind);
        EpisodeMetrics {
            collision_split: CollisionSplit {
                ego_at_fault: u64::from(kind == Some(EgoCollisionKind::EgoAtFault)),
                ego_hit_in_lane: u64::from(kind == Some(EgoCollisionKind::EgoHitInLane)),
                sv_sv: u64::from(e.sv_collisions),
            },
            safety: e.safety.clone(),
            decisions: e.decisions.len() as u64,
            decisions_by_layer: by_layer,
            nominal_split,
            collisions: u32::from(e.collision.is_some()),
            collision_time_s: e.collision.map(|c| clean(c.time_s)),
            collision_with: e.collision.map(|c| c.other_id),
            lane_changes,
            beta_switches,
            corrective_time_s: clean(corrective as f64 * e.decision_period_s),
            mean_speed_mps: if e.steps == 0 {
                0.0
            } else {
                e.ego_speed_sum / e.steps as f64
            },
            simulated_s: clean(e.simulated_s),
        }
    }
}

/// Solve-time statistics (ms) over a set of samples.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SolveTimeStats {
    /// Number of samples.
    pub samples: u64,
    /// Mean (ms).
    pub mean_ms: f64,
    /// 99th percentile, nearest rank (ms).
    pub p99_ms: f64,
    /// Maximum (ms).
    pub max_ms: f64,
}

impl SolveTimeStats {
    /// Statistics of samples in microseconds (sorted in place).
    pub fn from_us(samples: &mut [u64]) -> Self {
        if samples.is_empty() {
            return Self::default();
        }
        samples.sort_unstable();
        let n = samples.len();
        let sum: u64 = samples.iter().sum();
        SolveTimeStats {
            samples: n as u64,
            mean_ms: sum as f64 / n as f64 / 1000.0,
            p99_ms: stats::nearest_rank(samples, 0.99) as f64 / 1000.0,
            max_ms: samples[n - 1] as f64 / 1000.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::episode::{DecisionRecord, Episode};
    use protocol::Layer;

    fn record(index: u64, layer: Layer, lane: u8, beta: i8, corrective: usize) -> DecisionRecord {
        DecisionRecord {
            index,
            time_s: 0.4 * index as f64,
            layer: Some(layer),
            target_lane: lane,
            beta,
            corrective_svs: corrective,
            corrective_sv_ids: (1..=corrective as u32).collect(),
            svs_sent: 0,
            ego_x_m: 0.0,
            ego_y_m: 0.0,
            ego_speed_mps: 10.0,
            plan: Vec::new(),
            solve_us: 100 * (index + 1),
            request: None,
            nominal_class: None,
        }
    }

    #[test]
    fn counts_switches_lane_changes_layers_and_corrective_time() {
        let decisions = vec![
            record(0, Layer::Nominal, 2, 1, 0),
            record(1, Layer::Nominal, 2, 1, 1),
            record(2, Layer::GlobalRelaxation, 1, 0, 1),
            record(3, Layer::Fallback, 1, -1, 0),
            record(4, Layer::Nominal, 1, 0, 0),
            record(5, Layer::Nominal, 2, 0, 2),
        ];
        let e = Episode {
            decision_period_s: 0.4,
            initial_lane: 2,
            decisions,
            trajectory: Vec::new(),
            collision: None,
            sv_collisions: 0,
            steps: 24,
            simulated_s: 2.4,
            ego_speed_sum: 24.0 * 12.0,
            safety: SafetySummary::default(),
            hard_braking: Vec::new(),
        };
        let m = EpisodeMetrics::from_episode(&e);
        assert_eq!(m.decisions, 6);
        assert_eq!(
            m.decisions_by_layer,
            LayerCounts {
                nominal: 4,
                global_relaxation: 1,
                fallback: 1,
                ..LayerCounts::default()
            }
        );
        assert_eq!(m.beta_switches, 3, "1 -> 0 -> -1 -> 0");
        assert_eq!(m.lane_changes, 2, "2 -> 1 -> 2");
        assert!((m.corrective_time_s - 1.2).abs() < 1e-12);
        assert!((m.mean_speed_mps - 12.0).abs() < 1e-12);
        assert_eq!(m.collisions, 0);
        assert_eq!(e.solve_times_us(), vec![100, 200, 300, 400, 500, 600]);
    }

    #[test]
    fn solve_time_percentiles() {
        let mut us: Vec<u64> = (1..=200).rev().map(|k| k * 1000).collect();
        let s = SolveTimeStats::from_us(&mut us);
        assert_eq!(s.samples, 200);
        assert!((s.mean_ms - 100.5).abs() < 1e-9);
        assert_eq!(s.p99_ms, 198.0);
        assert_eq!(s.max_ms, 200.0);
        assert_eq!(SolveTimeStats::from_us(&mut []), SolveTimeStats::default());
    }
}
