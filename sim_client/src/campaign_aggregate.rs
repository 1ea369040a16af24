//! Aggregation of campaign trials into groups (one configuration and driver, or a driver
//! overall): the one definition of every campaign figure, used by the campaign's report and by
//! `compare`'s resampling alike.

use serde::{Deserialize, Serialize};

use crate::campaign::{CampaignEntry, DriverKind, TrialOutcome};
use crate::metrics::{clean, CollisionSplit, LayerCounts, SolveTimeStats};
use crate::safety::GroupSafety;

/// Aggregate over a set of episodes (one configuration and driver, or overall).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupResult {
    /// Configuration id (`None` for the overall row).
    pub config_id: Option<u32>,
    /// Lanes (`None` for the overall row).
    pub lanes: Option<u8>,
    /// SV count.
    pub sv_count: Option<u32>,
    /// Speed range (m/s).
    pub speed_range: Option<(f64, f64)>,
    /// Driver.
    pub driver: DriverKind,
    /// Episodes.
    pub trials: u64,
    /// Decisions.
    pub decisions: u64,
    /// Planner decisions by layer.
    pub decisions_by_layer: LayerCounts,
    /// Episodes with an ego collision.
    pub collisions: u64,
    /// Ego collisions by cause, and SV-SV contacts.
    pub collision_split: CollisionSplit,
    /// `collisions / trials`.
    pub collision_rate: f64,
    /// Nominal share of planner decisions (`None` for the IDM ego).
    pub nor: Option<f64>,
    /// The nominal decisions against the plain MPC (the paper's MPC: no violation allowance,
    /// band slack within `d_HS`).
    #[serde(default)]
    pub nominal_split: crate::metrics::NominalSplit,
    /// Share of planner decisions the plain MPC makes nominally: the figure that compares
    /// with the paper's NOR (`None` for the IDM ego).
    #[serde(default)]
    pub plain_nor: Option<f64>,
    /// Layer A share.
    pub gsrr: Option<f64>,
    /// Layer B share.
    pub fbr: Option<f64>,
    /// Solve times (wall clock, not reproducible).
    pub solve_time: SolveTimeStats,
    /// Mean ego speed, time weighted (m/s).
    pub mean_speed_mps: f64,
    /// Commanded lane changes per simulated minute.
    pub lane_changes_per_min: f64,
    /// Beta switches per simulated minute.
    pub beta_switches_per_min: f64,
    /// Simulated time (s).
    pub simulated_s: f64,
    /// Surrogate safety measures over the episodes.
    pub safety: GroupSafety,
}

pub(crate) fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// Aggregates outcomes (in the given order) into one group; `dt` is the simulator step.
pub fn aggregate<'a>(
    entry: Option<&CampaignEntry>,
    driver: DriverKind,
    outcomes: impl Iterator<Item = &'a TrialOutcome>,
    dt: f64,
) -> GroupResult {
    let outcomes: Vec<&TrialOutcome> = outcomes.collect();
    let mut split = CollisionSplit::default();
    let mut trials = 0u64;
    let mut decisions = 0u64;
    let mut layers = LayerCounts::default();
    let mut nominal_split = crate::metrics::NominalSplit::default();
    let mut collisions = 0u64;
    let mut simulated = 0.0;
    let mut speed_time = 0.0;
    let mut lane_changes = 0u64;
    let mut beta_switches = 0u64;
    let mut solve: Vec<u64> = Vec::new();
    for o in &outcomes {
        let m = &o.metrics;
        split.merge(&m.collision_split);
        trials += 1;
        decisions += m.decisions;
        layers.merge(&m.decisions_by_layer);
        nominal_split.merge(&m.nominal_split);
        collisions += u64::from(m.collisions);
        simulated += m.simulated_s;
        speed_time += m.mean_speed_mps * m.simulated_s;
        lane_changes += u64::from(m.lane_changes);
        beta_switches += u64::from(m.beta_switches);
        solve.extend_from_slice(&o.solve_us);
    }
    let planner = driver != DriverKind::IdmMobil;
    let total = layers.total();
    let minutes = simulated / 60.0;
    let per_min = |n: u64| if minutes > 0.0 { n as f64 / minutes } else { 0.0 };
    GroupResult {
        config_id: entry.map(|e| e.id),
        lanes: entry.map(|e| e.traffic.lanes),
        sv_count: entry.map(|e| e.traffic.sv_count),
        speed_range: entry.map(|e| e.traffic.speed_range),
        driver,
        trials,
        decisions,
        decisions_by_layer: layers,
        collisions,
        collision_split: split,
        collision_rate: ratio(collisions, trials),
        nor: planner.then(|| ratio(layers.nominal, total)),
        nominal_split,
        plain_nor: planner.then(|| ratio(nominal_split.plain_feasible(), total)),
        gsrr: planner.then(|| ratio(layers.global_relaxation, total)),
        fbr: planner.then(|| ratio(layers.fallback, total)),
        solve_time: SolveTimeStats::from_us(&mut solve),
        mean_speed_mps: if simulated > 0.0 { speed_time / simulated } else { 0.0 },
        lane_changes_per_min: per_min(lane_changes),
        beta_switches_per_min: per_min(beta_switches),
        simulated_s: clean(simulated),
        safety: GroupSafety::from_episodes(outcomes.iter().map(|o| &o.metrics.safety), dt),
    }
}
