//! The paper's Case 1 (demonstration) and Case 2 (hysteresis ablation), as pure runners.
//! Both run the project's planner and, beside it, the paper-literal preset when given.

use decision::PlannerConfig;
use serde::{Deserialize, Serialize};
use traffic::{Scenario, SimParams, SvBehaviour};

use crate::episode::{run_episode_observed, Driver, Episode, EpisodeSpec, StepObserver};
use crate::error::Result;
use crate::link::Transport;
use crate::metrics::EpisodeMetrics;

/// Simulated duration of Cases 1 and 2 (paper Table III), s.
pub const CASE_DURATION_S: f64 = 40.0;

/// The episode of Case 1: Table II scene, deterministic SVs, 40 s, full trajectory.
pub fn case1_spec(seed: u64, max_svs: usize) -> EpisodeSpec {
    EpisodeSpec {
        scenario: Scenario::case1(),
        params: SimParams {
            sv: SvBehaviour::deterministic(),
            ..SimParams::default()
        },
        seed,
        duration_s: CASE_DURATION_S,
        max_svs,
        record_trajectory: true,
        audit_nominal: None,
        trace_hard_braking: false,
    }
}

/// One planner run of a case.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseRun {
    /// The initial scene.
    pub scenario: Scenario,
    /// The planner configuration of the run (also used to redraw its SV predictions).
    pub config: PlannerConfig,
    /// Whether the planner's hysteresis was on.
    pub hysteresis: bool,
    /// Everything the episode recorded.
    pub episode: Episode,
    /// Its metrics.
    pub metrics: EpisodeMetrics,
}

/// Runs the Case 1 scene with the planner configured by `config`.
pub fn run_case(config: &PlannerConfig, transport: &Transport, seed: u64) -> Result<CaseRun> {
    run_case_observed(config, transport, seed, &mut ())
}

/// [`run_case`] with an observer of every simulator step (e.g. a recording).
pub fn run_case_observed(
    config: &PlannerConfig,
    transport: &Transport,
    seed: u64,
    observer: &mut dyn StepObserver,
) -> Result<CaseRun> {
    let spec = EpisodeSpec {
        audit_nominal: Some(config.clone()),
        ..case1_spec(seed, config.perception.max_svs)
    };
    let mut link = transport.connect(config.clone())?;
    let episode = run_episode_observed(&spec, Driver::Planner(link.as_mut()), observer)?;
    Ok(CaseRun {
        scenario: spec.scenario,
        config: config.clone(),
        hysteresis: config.hysteresis.enabled,
        metrics: episode.metrics(),
        episode,
    })
}

/// Case 1: the scene with `config` as given (default: hysteresis on).
pub fn run_case1(config: &PlannerConfig, transport: &Transport, seed: u64) -> Result<CaseRun> {
    run_case(config, transport, seed)
}

/// Case 1 with the project's planner and, when given, the paper-literal preset.
#[derive(Debug, Clone, PartialEq)]
pub struct Case1 {
    /// The planner as configured (through the given transport).
    pub planner: CaseRun,
    /// The paper-literal preset (in process: a planner process has one configuration).
    pub paper_literal: Option<CaseRun>,
}

/// Runs Case 1 for the planner and, if `paper` is given, for the preset as well.
pub fn run_case1_compared(
    config: &PlannerConfig,
    paper: Option<&PlannerConfig>,
    transport: &Transport,
    seed: u64,
) -> Result<Case1> {
    Ok(Case1 {
        planner: run_case(config, transport, seed)?,
        paper_literal: paper.map(|p| run_case(p, &Transport::InProcess, seed)).transpose()?,
    })
}

/// One configuration with hysteresis on and off.
#[derive(Debug, Clone, PartialEq)]
pub struct Ablation {
    /// Hysteresis on.
    pub with: CaseRun,
    /// Hysteresis off (no corrective regime), otherwise identical.
    pub without: CaseRun,
}

/// The figures of one ablation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AblationSummary {
    /// Beta switches with hysteresis (paper: 1).
    pub beta_switches_with: u32,
    /// Beta switches without hysteresis (paper: 33).
    pub beta_switches_without: u32,
    /// Full metrics with hysteresis.
    pub with_hysteresis: EpisodeMetrics,
    /// Full metrics without hysteresis.
    pub without_hysteresis: EpisodeMetrics,
}

impl Ablation {
    /// The summary of both runs.
    pub fn summary(&self) -> AblationSummary {
        AblationSummary {
            beta_switches_with: self.with.metrics.beta_switches,
            beta_switches_without: self.without.metrics.beta_switches,
            with_hysteresis: self.with.metrics.clone(),
            without_hysteresis: self.without.metrics.clone(),
        }
    }
}

/// Both configurations of Case 2.
#[derive(Debug, Clone, PartialEq)]
pub struct Case2 {
    /// The project's planner.
    pub planner: Ablation,
    /// The paper-literal preset, when run.
    pub paper_literal: Option<Ablation>,
}

/// The Case 2 summary written to `case2/summary.json`: the planner's figures at the top
/// level, the preset's under `paper_literal`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Case2Summary {
    /// The project's planner.
    #[serde(flatten)]
    pub planner: AblationSummary,
    /// The paper-literal preset.
    pub paper_literal: Option<AblationSummary>,
}

impl Case2 {
    /// The summary of every run.
    pub fn summary(&self) -> Case2Summary {
        Case2Summary {
            planner: self.planner.summary(),
            paper_literal: self.paper_literal.as_ref().map(Ablation::summary),
        }
    }
}

/// `config` with hysteresis forced on, and forced off: the two runs of an ablation.
pub fn ablation_configs(config: &PlannerConfig) -> (PlannerConfig, PlannerConfig) {
    let mut on = config.clone();
    on.hysteresis.enabled = true;
    let mut off = config.clone();
    off.hysteresis.enabled = false;
    (on, off)
}

/// The Case 1 scene, same seed, with hysteresis forced on and then off.
pub fn run_ablation(config: &PlannerConfig, transport: &Transport, seed: u64) -> Result<Ablation> {
    let (on, off) = ablation_configs(config);
    Ok(Ablation {
        with: run_case(&on, transport, seed)?,
        without: run_case(&off, transport, seed)?,
    })
}

/// Case 2: the ablation for the planner and, if `paper` is given, for the preset.
pub fn run_case2(
    config: &PlannerConfig,
    paper: Option<&PlannerConfig>,
    transport: &Transport,
    seed: u64,
) -> Result<Case2> {
    Ok(Case2 {
        planner: run_ablation(config, transport, seed)?,
        paper_literal: paper.map(|p| run_ablation(p, transport, seed)).transpose()?,
    })
}
