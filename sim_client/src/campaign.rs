//! Case 3: the randomized campaign over traffic configurations, in parallel.
//!
//! Work items are (configuration, trial, driver) triples pulled from a shared counter by
//! worker threads, each with its own planners. Every episode depends only on its seeds, and
//! results are aggregated in the fixed item order, so they do not depend on the thread count.

use std::path::Path;

use decision::PlannerConfig;
use serde::{Deserialize, Serialize};
use traffic::{Scenario, SimParams, SvBehaviour, TrafficConfig};

use crate::episode::{run_episode, Driver, EpisodeSpec, HardBrakingDecision};
use crate::error::{Result, SimClientError};
use crate::link::{PlannerLink, Transport};
use crate::metrics::{EpisodeMetrics, SolveTimeStats};

pub use crate::campaign_aggregate::{aggregate, GroupResult};

/// Episode duration of the campaign (75 decisions at T_h = 0.4 s), s.
pub const CAMPAIGN_DURATION_S: f64 = 30.0;

/// One traffic configuration and its trial count.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CampaignEntry {
    /// Configuration id (Table I id for the paper table).
    pub id: u32,
    /// Scene parameters.
    pub traffic: TrafficConfig,
    /// Number of trials.
    pub trials: u32,
}

/// The 18 configurations of Table I with the paper's trial counts.
pub fn paper_entries() -> Vec<CampaignEntry> {
    TrafficConfig::paper_table()
        .into_iter()
        .map(|e| CampaignEntry {
            id: u32::from(e.id),
            traffic: e.config,
            trials: e.trials,
        })
        .collect()
}

/// A configuration as written in a `--config` file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomConfig {
    /// Optional id (default: position in the list, from 1).
    pub id: Option<u32>,
    /// Lane count, 2..=5.
    pub lanes: u8,
    /// Number of SVs.
    #[serde(alias = "svs")]
    pub sv_count: u32,
    /// Speed range `[lo, hi]` (m/s).
    pub speed_range: (f64, f64),
    /// Number of trials.
    pub trials: u32,
    /// Initial position range (default `[0, 500]`).
    pub x_range: Option<(f64, f64)>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum ConfigFile {
    List(Vec<CustomConfig>),
    Table {
        #[serde(alias = "configs")]
        config: Vec<CustomConfig>,
    },
}

fn entries_from(list: Vec<CustomConfig>) -> Result<Vec<CampaignEntry>> {
    if list.is_empty() {
        return Err(SimClientError::Config("the configuration list is empty".into()));
    }
    let entries: Vec<CampaignEntry> = list
        .into_iter()
        .enumerate()
        .map(|(k, c)| {
            let mut traffic = TrafficConfig::new(c.lanes, c.sv_count, c.speed_range);
            if let Some(x) = c.x_range {
                traffic.x_range = x;
            }
            CampaignEntry {
                id: c.id.unwrap_or(k as u32 + 1),
                traffic,
                trials: c.trials,
            }
        })
        .collect();
    for (k, e) in entries.iter().enumerate() {
        e.traffic
            .validate()
            .map_err(|err| SimClientError::Config(format!("configuration {}: {err}", e.id)))?;
        if entries[..k].iter().any(|o| o.id == e.id) {
            return Err(SimClientError::Config(format!("duplicate configuration id {}", e.id)));
        }
    }
    Ok(entries)
}

/// Parses a configuration list: JSON (a list, or `{"config": [...]}`) or TOML
/// (`[[config]]` tables). Each item: `lanes`, `sv_count`, `speed_range`, `trials`, optional
/// `id` and `x_range`.
pub fn parse_entries(text: &str, json: bool) -> Result<Vec<CampaignEntry>> {
    let file: ConfigFile = if json {
        serde_json::from_str(text)?
    } else {
        toml::from_str(text).map_err(|e| SimClientError::Config(e.to_string()))?
    };
    match file {
        ConfigFile::List(l) | ConfigFile::Table { config: l } => entries_from(l),
    }
}

/// Reads a configuration file; `.json` is JSON, anything else TOML.
pub fn load_entries(path: &Path) -> Result<Vec<CampaignEntry>> {
    let text = std::fs::read_to_string(path).map_err(|e| SimClientError::io(path, e))?;
    let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    parse_entries(&text, json)
}

/// Scales every trial count by `scale`, keeping at least one trial per configuration.
pub fn scale_trials(entries: &[CampaignEntry], scale: f64) -> Result<Vec<CampaignEntry>> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(SimClientError::Config("--trials-scale must be positive".into()));
    }
    Ok(entries
        .iter()
        .map(|e| CampaignEntry {
            trials: ((f64::from(e.trials) * scale).round() as u32).max(1),
            ..*e
        })
        .collect())
}

/// Who drives the ego in a campaign run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriverKind {
    /// The planner with the paper-literal preset (`deploy/paper.toml`).
    PaperLiteral,
    /// The planner as configured.
    Planner,
    /// The planner with hysteresis off.
    PlannerNoHysteresis,
    /// The simulator's IDM + MOBIL ego.
    IdmMobil,
}

impl DriverKind {
    /// Name used in files.
    pub fn name(self) -> &'static str {
        match self {
            DriverKind::PaperLiteral => "paper_literal",
            DriverKind::Planner => "planner",
            DriverKind::PlannerNoHysteresis => "planner_no_hysteresis",
            DriverKind::IdmMobil => "idm_mobil",
        }
    }

    /// The planner configuration this driver runs with (`None`: the IDM + MOBIL ego).
    pub fn planner_config(self, settings: &CampaignSettings) -> Option<PlannerConfig> {
        let mut c = settings.planner.clone();
        match self {
            DriverKind::PaperLiteral => settings.paper_literal.clone(),
            DriverKind::Planner => Some(c),
            DriverKind::PlannerNoHysteresis => {
                c.hysteresis.enabled = false;
                Some(c)
            }
            DriverKind::IdmMobil => None,
        }
    }
}

/// Everything a campaign needs.
#[derive(Debug, Clone)]
pub struct CampaignSettings {
    /// Configurations with their (already scaled) trial counts.
    pub entries: Vec<CampaignEntry>,
    /// Base seed.
    pub seed: u64,
    /// Worker threads (at least 1).
    pub threads: usize,
    /// Also run the planner without hysteresis and the IDM + MOBIL ego.
    pub baselines: bool,
    /// Episode duration (s).
    pub duration_s: f64,
    /// Planner configuration (the "planner" driver uses it as is).
    pub planner: PlannerConfig,
    /// The paper-literal preset, run as a baseline when given.
    pub paper_literal: Option<PlannerConfig>,
    /// Transport to the planner.
    pub transport: Transport,
    /// Simulator parameters.
    pub params: SimParams,
    /// Keep the decisions of the "planner" driver that brake hard
    /// ([`CampaignResults::hard_braking`]); the baselines are not traced.
    pub trace_hard_braking: bool,
}

impl CampaignSettings {
    /// Defaults: the given entries, 30 s episodes, baselines on, default simulator.
    pub fn new(entries: Vec<CampaignEntry>, seed: u64, threads: usize) -> Self {
        CampaignSettings {
            entries,
            seed,
            threads,
            baselines: true,
            duration_s: CAMPAIGN_DURATION_S,
            planner: PlannerConfig::default(),
            paper_literal: None,
            transport: Transport::InProcess,
            params: SimParams::default(),
            trace_hard_braking: false,
        }
    }

    /// The drivers this campaign runs, in report order.
    pub fn drivers(&self) -> Vec<DriverKind> {
        if self.baselines {
            let paper = self.paper_literal.as_ref().map(|_| DriverKind::PaperLiteral);
            paper
                .into_iter()
                .chain([
                    DriverKind::Planner,
                    DriverKind::PlannerNoHysteresis,
                    DriverKind::IdmMobil,
                ])
                .collect()
        } else {
            vec![DriverKind::Planner]
        }
    }

    /// Number of episodes the campaign runs.
    pub fn episode_count(&self) -> usize {
        let trials: u64 = self.entries.iter().map(|e| u64::from(e.trials)).sum();
        trials as usize * self.drivers().len()
    }
}

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Seed of one trial's scenario, from (base seed, configuration id, trial index).
pub fn trial_seed(base: u64, config_id: u32, trial: u32) -> u64 {
    splitmix64(splitmix64(splitmix64(base) ^ u64::from(config_id)) ^ u64::from(trial))
}

/// The episode of one trial (identical for every driver).
pub fn trial_spec(entry: &CampaignEntry, trial: u32, settings: &CampaignSettings) -> Result<EpisodeSpec> {
    let seed = trial_seed(settings.seed, entry.id, trial);
    Ok(EpisodeSpec {
        scenario: Scenario::random(&entry.traffic, seed)?,
        params: settings.params,
        seed: splitmix64(seed ^ 0x5EED),
        duration_s: settings.duration_s,
        max_svs: settings.planner.perception.max_svs,
        record_trajectory: false,
        audit_nominal: None,
        trace_hard_braking: false,
    })
}

/// Outcome of one episode of the campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialOutcome {
    /// Configuration id.
    pub config_id: u32,
    /// Trial index.
    pub trial: u32,
    /// Driver.
    pub driver: DriverKind,
    /// Reproducible metrics.
    pub metrics: EpisodeMetrics,
    /// Planner solve times (µs).
    pub solve_us: Vec<u64>,
    /// Its hard-braking decisions (with [`CampaignSettings::trace_hard_braking`]).
    pub hard_braking: Vec<HardBrakingDecision>,
}

/// A hard-braking decision of a campaign, with the trial it belongs to.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TracedHardBraking {
    /// The driver (a planner preset).
    pub driver: DriverKind,
    /// Configuration id.
    pub config_id: u32,
    /// Trial index.
    pub trial: u32,
    /// The trial's scenario seed ([`trial_seed`]; the simulator's is derived from it).
    pub seed: u64,
    /// The decision and its situation.
    #[serde(flatten)]
    pub decision: HardBrakingDecision,
}

/// Everything a campaign produced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CampaignResults {
    /// Base seed.
    pub seed: u64,
    /// Episode duration (s).
    pub duration_s: f64,
    /// How the SVs drove: their random maneuver switches (`settings.params.sv`).
    #[serde(default)]
    pub sv: SvBehaviour,
    /// Configurations run.
    pub entries: Vec<CampaignEntry>,
    /// Drivers run, in report order.
    pub drivers: Vec<DriverKind>,
    /// Per configuration and driver, configuration-major.
    pub groups: Vec<GroupResult>,
    /// Per driver over all configurations.
    pub overall: Vec<GroupResult>,
    /// Wall time of the whole campaign (s).
    pub wall_time_s: f64,
    /// Worker threads used.
    pub threads: usize,
    /// The "planner" driver's decisions that braked hard, in (configuration, trial) order
    /// whatever the thread count; `None` unless [`CampaignSettings::trace_hard_braking`]. Not
    /// part of results.json (`hard-braking.jsonl`).
    #[serde(skip)]
    pub hard_braking: Option<Vec<TracedHardBraking>>,
    /// Every trial of every driver, in (configuration, trial, driver) order. Not part of
    /// results.json (`trials.jsonl`).
    #[serde(skip)]
    pub trials: Vec<TrialRecord>,
}

/// One trial of one driver as trials.jsonl holds it: what `compare` pairs and resamples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialRecord {
    /// Driver.
    pub driver: DriverKind,
    /// Configuration id.
    pub config_id: u32,
    /// Trial index.
    pub trial: u32,
    /// The trial's scenario seed ([`trial_seed`]).
    pub seed: u64,
    /// The simulator step (s), which converts the safety figures' steps to time.
    pub dt_s: f64,
    /// The episode's duration (s).
    pub duration_s: f64,
    /// The configuration's traffic: with the seed and `sv`, what makes two runs' trial the
    /// same.
    pub traffic: TrafficConfig,
    /// How the SVs drove (their random maneuver switches).
    #[serde(default)]
    pub sv: SvBehaviour,
    /// The trial's reproducible metrics.
    pub metrics: EpisodeMetrics,
}

impl CampaignResults {
    /// A copy without any wall-clock quantity (for reproducibility checks).
    pub fn without_timing(&self) -> CampaignResults {
        let mut r = self.clone();
        r.wall_time_s = 0.0;
        r.threads = 0;
        for g in r.groups.iter_mut().chain(r.overall.iter_mut()) {
            g.solve_time = SolveTimeStats {
                samples: g.solve_time.samples,
                ..SolveTimeStats::default()
            };
        }
        r
    }

    /// The group of a configuration and driver.
    pub fn group(&self, config_id: u32, driver: DriverKind) -> Option<&GroupResult> {
        self.groups
            .iter()
            .find(|g| g.config_id == Some(config_id) && g.driver == driver)
    }

    /// The overall row of a driver.
    pub fn overall_for(&self, driver: DriverKind) -> Option<&GroupResult> {
        self.overall.iter().find(|g| g.driver == driver)
    }
}

struct Item {
    entry: usize,
    trial: u32,
    driver: DriverKind,
}

struct Worker<'s> {
    settings: &'s CampaignSettings,
    links: Vec<(DriverKind, Box<dyn PlannerLink>)>,
}

impl Worker<'_> {
    fn run(&mut self, item: &Item) -> Result<TrialOutcome> {
        let entry = &self.settings.entries[item.entry];
        let mut spec = trial_spec(entry, item.trial, self.settings)?;
        let episode = match item.driver.planner_config(self.settings) {
            None => run_episode(&spec, Driver::IdmMobil)?,
            Some(config) => {
                spec.audit_nominal = Some(config.clone());
                // The baselines run other configurations: their situations would be explained
                // with the wrong planner.
                spec.trace_hard_braking = self.settings.trace_hard_braking && item.driver == DriverKind::Planner;
                let pos = match self.links.iter().position(|(d, _)| *d == item.driver) {
                    Some(p) => p,
                    None => {
                        let link = self.settings.transport.connect(config)?;
                        self.links.push((item.driver, link));
                        self.links.len() - 1
                    }
                };
                run_episode(&spec, Driver::Planner(self.links[pos].1.as_mut()))?
            }
        };
        Ok(TrialOutcome {
            config_id: entry.id,
            trial: item.trial,
            driver: item.driver,
            metrics: episode.metrics(),
            solve_us: episode.solve_times_us(),
            hard_braking: episode.hard_braking,
        })
    }
}

/// Runs the campaign. `on_episode` is called once per finished episode (progress display).
pub fn run_campaign(settings: &CampaignSettings, on_episode: &(dyn Fn() + Sync)) -> Result<CampaignResults> {
    let started = std::time::Instant::now();
    if settings.entries.is_empty() {
        return Err(SimClientError::Config("no configuration to run".into()));
    }
    let drivers = settings.drivers();
    let mut items = Vec::with_capacity(settings.episode_count());
    for (k, e) in settings.entries.iter().enumerate() {
        for trial in 0..e.trials {
            for &driver in &drivers {
                items.push(Item {
                    entry: k,
                    trial,
                    driver,
                });
            }
        }
    }
    let threads = settings.threads.clamp(1, items.len().max(1));
    let outcomes = crate::pool::run_ordered(
        &items,
        threads,
        || Worker {
            settings,
            links: Vec::new(),
        },
        |worker, item| worker.run(item),
        on_episode,
    )?;
    let mut groups = Vec::new();
    for e in &settings.entries {
        for &d in &drivers {
            groups.push(aggregate(
                Some(e),
                d,
                outcomes.iter().filter(|o| o.config_id == e.id && o.driver == d),
                settings.params.dt,
            ));
        }
    }
    let overall = drivers
        .iter()
        .map(|&d| aggregate(None, d, outcomes.iter().filter(|o| o.driver == d), settings.params.dt))
        .collect();
    let hard_braking = settings.trace_hard_braking.then(|| {
        outcomes
            .iter()
            .flat_map(|o| {
                o.hard_braking.iter().map(|d| TracedHardBraking {
                    driver: o.driver,
                    config_id: o.config_id,
                    trial: o.trial,
                    seed: trial_seed(settings.seed, o.config_id, o.trial),
                    decision: d.clone(),
                })
            })
            .collect()
    });
    let trials = outcomes
        .iter()
        .map(|o| TrialRecord {
            driver: o.driver,
            config_id: o.config_id,
            trial: o.trial,
            seed: trial_seed(settings.seed, o.config_id, o.trial),
            dt_s: settings.params.dt,
            duration_s: settings.duration_s,
            traffic: settings
                .entries
                .iter()
                .find(|e| e.id == o.config_id)
                .expect("every outcome is of a configuration run")
                .traffic,
            sv: settings.params.sv,
            metrics: o.metrics.clone(),
        })
        .collect();
    Ok(CampaignResults {
        seed: settings.seed,
        duration_s: settings.duration_s,
        sv: settings.params.sv,
        entries: settings.entries.clone(),
        drivers,
        groups,
        overall,
        wall_time_s: started.elapsed().as_secs_f64(),
        threads,
        hard_braking,
        trials,
    })
}
