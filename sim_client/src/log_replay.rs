//! `sim_client replay FILE.mcap`: log replay of traffic. The SVs follow their recorded
//! trajectories (non-reactive), the ego is re-planned by the planner from its recorded start,
//! and the run is scored like a campaign trial.
//!
//! A recording needs `/sim/trial` (one `TrialInfo`) and `/sim/vehicles` (every vehicle at
//! every low-level step, the ego with id 0); see docs/recording.md.

use std::collections::BTreeMap;
use std::path::Path;

use decision::PlannerConfig;
use serde::Serialize;
use traffic::{Road, Scenario, SimParams, VehicleInit, World};

use crate::episode::{run_episode_observed, Driver, Episode, EpisodeSpec, StepObserver};
use crate::error::{Result, SimClientError};
use crate::link::Transport;
use crate::metrics::EpisodeMetrics;
use crate::record::{TrialInfo, VehicleStates, TRIAL_TOPIC, VEHICLES_TOPIC};

/// A recorded traffic log.
#[derive(Debug, Clone, PartialEq)]
pub struct TrafficLog {
    /// The road and settings.
    pub info: TrialInfo,
    /// The vehicles at every step, by step index.
    pub steps: Vec<VehicleStates>,
}

/// Reads the traffic of a simulator recording (or a foreign one with the same channels).
pub fn read_traffic_log(path: &Path) -> Result<TrafficLog> {
    let messages = recording::read_messages(path)?;
    let mut info = None;
    let mut steps = Vec::new();
    for (index, m) in messages.iter().enumerate() {
        match m.topic.as_str() {
            TRIAL_TOPIC => info = Some(m.decode::<TrialInfo>(path, index, "TrialInfo")?),
            VEHICLES_TOPIC => steps.push(m.decode::<VehicleStates>(path, index, "VehicleStates")?),
            _ => {}
        }
    }
    let missing = |topic: &str, needed: &'static str| recording::RecordingError::MissingChannel {
        path: path.to_owned(),
        topic: topic.to_owned(),
        needed,
    };
    let info = info.ok_or_else(|| missing(TRIAL_TOPIC, "the road and the low-level step"))?;
    if steps.is_empty() {
        return Err(missing(VEHICLES_TOPIC, "the vehicles' trajectories").into());
    }
    steps.sort_by_key(|s| s.step);
    if !steps[0].vehicles.iter().any(|v| v.id == 0) {
        return Err(SimClientError::Config(format!(
            "{}: the first `{VEHICLES_TOPIC}` message has no ego (id 0)",
            path.display()
        )));
    }
    Ok(TrafficLog { info, steps })
}

/// A seeded change of the recorded SVs: each SV's trajectory shifted along the road by its
/// own constant offset in `[-max_offset_m, max_offset_m]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Perturbation {
    /// Seed of the offsets.
    pub seed: u64,
    /// Largest offset, m.
    pub max_offset_m: f64,
}

impl Perturbation {
    /// The offset of the SV with recorded id `id` (splitmix64 of seed and id).
    pub fn offset_m(&self, id: u32) -> f64 {
        let mut z = self.seed ^ (u64::from(id).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        let unit = (z >> 11) as f64 / (1u64 << 53) as f64; // [0, 1)
        (2.0 * unit - 1.0) * self.max_offset_m
    }
}

/// How far the re-planned ego strayed from the recorded one.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct EgoDeviation {
    /// Steps compared.
    pub steps: usize,
    /// Largest longitudinal difference, m.
    pub max_dx_m: f64,
    /// Largest lateral difference, m.
    pub max_dy_m: f64,
    /// Largest speed difference, m/s.
    pub max_dv_mps: f64,
}

/// The outcome of a log replay.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogReplayReport {
    /// The trial's scores (collisions, speed, safety metrics), as in a campaign.
    pub metrics: EpisodeMetrics,
    /// The ego against its recorded trajectory.
    pub ego_deviation: EgoDeviation,
    /// SVs that followed a recorded trajectory.
    pub svs: usize,
}

fn lane_of(info: &TrialInfo, y_m: f64) -> u8 {
    let from_left = (y_m / info.lane_width_m).round();
    let lane = f64::from(info.lanes) - from_left;
    lane.clamp(1.0, f64::from(info.lanes.max(1))) as u8
}

/// Puts the SVs on their recorded states at every step.
struct Follower<'a> {
    by_step: BTreeMap<u64, &'a VehicleStates>,
    /// Recorded SV id -> the world's id.
    world_id: BTreeMap<u32, u32>,
    perturbation: Option<Perturbation>,
    info: &'a TrialInfo,
}

impl StepObserver for Follower<'_> {
    fn after_step(&mut self, world: &mut World) -> Result<()> {
        let Some(states) = self.by_step.get(&world.step_index()) else {
            return Ok(());
        };
        let mut snapshot = world.snapshot();
        for r in states.vehicles.iter().filter(|v| v.id != 0) {
            let Some(id) = self.world_id.get(&r.id) else { continue };
            let Some(v) = snapshot.vehicles.iter_mut().find(|v| v.id == *id) else {
                continue;
            };
            let lane = if r.lane == 0 { lane_of(self.info, r.y_m) } else { r.lane };
            v.x = r.x_m + self.perturbation.map_or(0.0, |p| p.offset_m(r.id));
            v.y = r.y_m;
            v.vy = r.vy_mps;
            v.v = r.v_mps;
            v.a = r.a_mps2;
            v.lane = lane;
            v.target_lane = if r.target_lane == 0 { lane } else { r.target_lane };
            v.beta = r.beta;
        }
        *world = World::from_snapshot(snapshot)?;
        Ok(())
    }
}

/// Replays `log`: the ego re-planned through `transport` with `config`, the SVs on their
/// recorded (optionally perturbed) trajectories.
pub fn replay_log(
    log: &TrafficLog,
    config: &PlannerConfig,
    transport: &Transport,
    perturbation: Option<Perturbation>,
) -> Result<(LogReplayReport, Episode)> {
    let info = &log.info;
    let first = &log.steps[0];
    let ego = first.vehicles.iter().find(|v| v.id == 0).expect("checked when read");
    let mut sv_ids: Vec<u32> = first.vehicles.iter().map(|v| v.id).filter(|&id| id != 0).collect();
    sv_ids.sort_unstable();
    let init = |v: &crate::record::RecordedVehicle, desired: f64| VehicleInit {
        x: v.x_m,
        lane: if v.lane == 0 { lane_of(info, v.y_m) } else { v.lane },
        v: v.v_mps,
        desired_speed: desired,
    };
    let svs = sv_ids
        .iter()
        .filter_map(|id| first.vehicles.iter().find(|v| v.id == *id))
        .map(|v| init(v, v.v_mps))
        .collect();
    let scenario = Scenario {
        road: Road {
            lanes: info.lanes,
            lane_width: info.lane_width_m,
            speed_limit: info.speed_limit_mps,
        },
        ego: init(ego, info.ego_desired_speed_mps),
        svs,
    };
    let params = info.params.unwrap_or(SimParams {
        dt: info.low_level_step_s,
        ..SimParams::default()
    });
    let last = log.steps.last().map_or(0.0, |s| s.time_s);
    let spec = EpisodeSpec {
        scenario,
        params,
        seed: info.seed,
        duration_s: last - first.time_s,
        max_svs: if info.max_svs == 0 {
            config.perception.max_svs
        } else {
            info.max_svs
        },
        record_trajectory: true,
        audit_nominal: None,
        trace_hard_braking: false,
    };
    let mut follower = Follower {
        by_step: log.steps.iter().map(|s| (s.step - first.step, s)).collect(),
        world_id: sv_ids.iter().enumerate().map(|(k, &id)| (id, k as u32 + 1)).collect(),
        perturbation,
        info,
    };
    let mut link = transport.connect(config.clone())?;
    let episode = run_episode_observed(&spec, Driver::Planner(link.as_mut()), &mut follower)?;
    let mut deviation = EgoDeviation::default();
    for s in episode.trajectory.iter().filter(|s| s.id == 0) {
        let Some(recorded) = follower
            .by_step
            .get(&s.step)
            .and_then(|r| r.vehicles.iter().find(|v| v.id == 0))
        else {
            continue;
        };
        deviation.steps += 1;
        deviation.max_dx_m = deviation.max_dx_m.max((s.x_m - recorded.x_m).abs());
        deviation.max_dy_m = deviation.max_dy_m.max((s.y_m - recorded.y_m).abs());
        deviation.max_dv_mps = deviation.max_dv_mps.max((s.v_mps - recorded.v_mps).abs());
    }
    let report = LogReplayReport {
        metrics: episode.metrics(),
        ego_deviation: deviation,
        svs: sv_ids.len(),
    };
    Ok((report, episode))
}
