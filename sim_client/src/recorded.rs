//! Recorded runs: `case1 --record`, `case2 --record` and `campaign --record`. Every trial is
//! run with a [`GroundTruth`] observer and written with [`write_trial`], one MCAP file per
//! trial (docs/recording.md).

use std::path::{Path, PathBuf};

use decision::PlannerConfig;

use crate::campaign::{trial_spec, CampaignSettings, DriverKind};
use crate::cases::{self, Ablation, Case2, CaseRun};
use crate::episode::{run_episode_observed, Driver, Episode, EpisodeSpec, StepObserver};
use crate::error::{Result, SimClientError};
use crate::link::Transport;
use crate::record::{write_trial, GroundTruth, TrialInfo};

/// The `/sim/trial` message of an episode.
pub fn trial_info(label: impl Into<String>, spec: &EpisodeSpec) -> TrialInfo {
    TrialInfo {
        label: label.into(),
        seed: spec.seed,
        lanes: spec.scenario.road.lanes,
        lane_width_m: spec.scenario.road.lane_width,
        speed_limit_mps: spec.scenario.road.speed_limit,
        ego_desired_speed_mps: spec.scenario.ego.desired_speed,
        low_level_step_s: spec.params.dt,
        max_svs: spec.max_svs,
        params: Some(spec.params),
    }
}

/// `base` with `suffix` before its `.mcap`: `run.mcap` + `with_hysteresis` is
/// `run.with_hysteresis.mcap`.
pub fn suffixed(base: &Path, suffix: &str) -> PathBuf {
    let stem = match base.extension() {
        Some(ext) if ext == "mcap" => base.file_stem(),
        _ => base.file_name(),
    }
    .map(|s| s.to_string_lossy().into_owned())
    .unwrap_or_default();
    base.with_file_name(format!("{stem}.{suffix}.mcap"))
}

/// Runs the Case 1 scene with `config` and records it to `path` under `label`; the run and
/// the files written.
pub fn record_case(
    label: &str,
    config: &PlannerConfig,
    transport: &Transport,
    seed: u64,
    path: &Path,
) -> Result<(CaseRun, Vec<PathBuf>)> {
    record_case_observed(label, config, transport, seed, path, &mut ())
}

/// [`record_case`] with `also` observing the run too (e.g. the live view).
pub fn record_case_observed(
    label: &str,
    config: &PlannerConfig,
    transport: &Transport,
    seed: u64,
    path: &Path,
    also: &mut dyn StepObserver,
) -> Result<(CaseRun, Vec<PathBuf>)> {
    let mut truth = GroundTruth::default();
    let run = cases::run_case_observed(config, transport, seed, &mut (&mut truth, also))?;
    let info = trial_info(label, &cases::case1_spec(seed, config.perception.max_svs));
    let files = write_trial(path, &info, &truth.steps, &run.episode)?;
    Ok((run, files))
}

/// Where `case2 --record BASE` writes a run: `BASE.with_hysteresis.mcap`,
/// `BASE.without_hysteresis.mcap`, and for the paper-literal preset
/// `BASE.paper_literal.with_hysteresis.mcap` and `BASE.paper_literal.without_hysteresis.mcap`
/// (the suffixes of the run's files in `out/case2/`).
pub fn case2_path(base: &Path, paper_literal: bool, hysteresis: bool) -> PathBuf {
    let run = if hysteresis {
        "with_hysteresis"
    } else {
        "without_hysteresis"
    };
    if paper_literal {
        suffixed(base, &format!("paper_literal.{run}"))
    } else {
        suffixed(base, run)
    }
}

fn record_ablation(
    config: &PlannerConfig,
    paper_literal: bool,
    transport: &Transport,
    seed: u64,
    base: &Path,
    files: &mut Vec<PathBuf>,
) -> Result<Ablation> {
    let (on, off) = cases::ablation_configs(config);
    let mut runs = Vec::with_capacity(2);
    for (config, hysteresis) in [(on, true), (off, false)] {
        let label = format!(
            "case2 {}{} hysteresis",
            if paper_literal { "paper_literal " } else { "" },
            if hysteresis { "with" } else { "without" }
        );
        let path = case2_path(base, paper_literal, hysteresis);
        let (run, written) = record_case(&label, &config, transport, seed, &path)?;
        files.extend(written);
        runs.push(run);
    }
    let without = runs.pop().expect("two runs");
    let with = runs.pop().expect("two runs");
    Ok(Ablation { with, without })
}

/// Case 2 ([`cases::run_case2`]) with every run recorded next to `base` (see
/// [`case2_path`]); the case and the files written.
pub fn record_case2(
    config: &PlannerConfig,
    paper: Option<&PlannerConfig>,
    transport: &Transport,
    seed: u64,
    base: &Path,
) -> Result<(Case2, Vec<PathBuf>)> {
    let mut files = Vec::new();
    let planner = record_ablation(config, false, transport, seed, base, &mut files)?;
    let paper_literal = paper
        .map(|p| record_ablation(p, true, transport, seed, base, &mut files))
        .transpose()?;
    Ok((Case2 { planner, paper_literal }, files))
}

/// Where `campaign --record DIR` writes a trial: `DIR/config03-trial0-planner.mcap`.
pub fn campaign_trial_path(dir: &Path, config_id: u32, trial: u32, driver: DriverKind) -> PathBuf {
    dir.join(format!("config{config_id:02}-trial{trial}-{}.mcap", driver.name()))
}

/// Runs trial `trial` of configuration `entry` with `driver` again and records it.
fn record_campaign_trial(
    settings: &CampaignSettings,
    entry: usize,
    trial: u32,
    driver: DriverKind,
    dir: &Path,
) -> Result<Vec<PathBuf>> {
    let entry = &settings.entries[entry];
    let spec = trial_spec(entry, trial, settings)?;
    let mut truth = GroundTruth::default();
    let episode: Episode = match driver.planner_config(settings) {
        None => run_episode_observed(&spec, Driver::IdmMobil, &mut truth)?,
        Some(config) => {
            let mut link = settings.transport.connect(config)?;
            run_episode_observed(&spec, Driver::Planner(link.as_mut()), &mut truth)?
        }
    };
    let label = format!("campaign config {} trial {trial} {}", entry.id, driver.name());
    let path = campaign_trial_path(dir, entry.id, trial, driver);
    write_trial(&path, &trial_info(label, &spec), &truth.steps, &episode)
}

/// Records the first `trials` trials of every configuration, for every driver of the
/// campaign, into `dir` (see [`campaign_trial_path`]); the files written.
///
/// The trials are run again with the campaign's seeds after the campaign (on
/// `settings.threads` threads): the simulator and the planner are deterministic, so they are
/// the trials the campaign scored, and the campaign itself pays nothing for the recording.
pub fn record_campaign_trials(settings: &CampaignSettings, dir: &Path, trials: u32) -> Result<Vec<PathBuf>> {
    let drivers = settings.drivers();
    let items: Vec<(usize, u32, DriverKind)> = settings
        .entries
        .iter()
        .enumerate()
        .flat_map(|(i, e)| (0..trials.min(e.trials)).map(move |t| (i, t)))
        .flat_map(|(i, t)| drivers.iter().map(move |&d| (i, t, d)))
        .collect();
    std::fs::create_dir_all(dir).map_err(|e| SimClientError::io(dir, e))?;
    let files = crate::pool::run_ordered(
        &items,
        settings.threads,
        || (),
        |_, &(entry, trial, driver)| record_campaign_trial(settings, entry, trial, driver, dir),
        &|| {},
    )?;
    Ok(files.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recordings_are_named_after_their_run() {
        let base = Path::new("out/run.mcap");
        assert_eq!(suffixed(base, "x"), Path::new("out/run.x.mcap"));
        assert_eq!(suffixed(Path::new("run"), "x"), Path::new("run.x.mcap"));
        assert_eq!(case2_path(base, false, true), Path::new("out/run.with_hysteresis.mcap"));
        assert_eq!(
            case2_path(base, true, false),
            Path::new("out/run.paper_literal.without_hysteresis.mcap")
        );
        assert_eq!(
            campaign_trial_path(Path::new("rec"), 3, 0, DriverKind::PlannerNoHysteresis),
            Path::new("rec/config03-trial0-planner_no_hysteresis.mcap")
        );
    }

    #[test]
    fn a_recorded_campaign_trial_is_the_trial_the_campaign_ran() {
        let mut entries = crate::campaign::paper_entries()[..1].to_vec();
        entries[0].trials = 1;
        let mut settings = CampaignSettings::new(entries, 5, 2);
        settings.duration_s = 6.0;
        let results = crate::campaign::run_campaign(&settings, &|| {}).expect("campaign");
        let dir = tempfile::tempdir().expect("temp dir");
        // At most the trials the configuration has.
        let files = record_campaign_trials(&settings, dir.path(), 3).expect("recorded");
        let drivers = settings.drivers();
        assert_eq!(files.len(), drivers.len());
        let id = settings.entries[0].id;
        for (file, driver) in files.iter().zip(drivers) {
            assert_eq!(*file, campaign_trial_path(dir.path(), id, 0, driver));
            let log = crate::log_replay::read_traffic_log(file).expect("read back");
            assert_eq!(
                log.info.seed,
                trial_spec(&settings.entries[0], 0, &settings).expect("spec").seed
            );
            let decisions = recording::read_messages(file)
                .expect("read")
                .iter()
                .filter(|m| m.topic == crate::record::DECISION_TOPIC)
                .count() as u64;
            let group = results.group(id, driver).expect("group");
            assert_eq!(decisions, group.decisions, "{driver:?}");
            let steps = log.steps.len() as u64 - 1;
            let simulated = steps as f64 * settings.params.dt;
            assert!(
                (simulated - group.simulated_s).abs() < 1e-6,
                "{driver:?}: the same run, to the same end ({simulated} s, {} s)",
                group.simulated_s
            );
        }
    }
}
