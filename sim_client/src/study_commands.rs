//! `sim_client case1`, `case2` and `campaign`: the paper's studies, optionally recorded.

use std::io::IsTerminal;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Result;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use sim_client::campaign::{self, CampaignSettings};
use sim_client::episode::StepObserver;
use sim_client::live::{LiveTrial, Pace};
use sim_client::record::{TrialInfo, SCENE_TOPIC};
use sim_client::{cases, recorded, report, Transport};
use traffic::SvBehaviour;

use super::{print_files, Common, TransportKind};

/// The paper-literal preset of the case and campaign commands.
#[derive(Args)]
pub struct PaperArgs {
    /// Planner TOML of the paper-literal preset (default: the embedded deploy/paper.toml).
    #[arg(long, value_name = "FILE")]
    paper_config: Option<PathBuf>,
}

impl PaperArgs {
    pub fn config(&self) -> Result<decision::PlannerConfig> {
        Ok(sim_client::presets::paper_literal(self.paper_config.as_deref())?)
    }
}

/// The live view of a case (docs/live-view.md).
#[derive(Args)]
pub struct LiveArgs {
    /// Serve the planner's trial live to Foxglove on this address (IP:PORT; without a value
    /// 127.0.0.1:8765): the world, the decisions and the 3D scene of the recording's
    /// channels, paced at real time.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
    foxglove: Option<SocketAddr>,
    /// With --foxglove: run as fast as possible instead of at real time.
    #[arg(long, requires = "foxglove")]
    fast: bool,
    /// With --foxglove: before starting, wait this long at most (e.g. `60s`) for a viewer to
    /// subscribe to the scene.
    #[arg(long, value_name = "D", value_parser = humantime::parse_duration, requires = "foxglove")]
    foxglove_wait: Option<Duration>,
}

impl LiveArgs {
    /// The live view of the trial `info` describes, if asked for (having waited for a
    /// viewer if asked to).
    fn start(&self, info: TrialInfo) -> Result<Option<LiveTrial>> {
        let Some(addr) = self.foxglove else {
            return Ok(None);
        };
        let pace = if self.fast { Pace::Fast } else { Pace::RealTime };
        let live = LiveTrial::start(&live_view::LiveOptions::new(addr, "hmdp sim_client"), info, pace)?;
        let addr = live.server().local_addr();
        println!("live view: open ws://{addr} in Foxglove (3D panel: topic {SCENE_TOPIC}, display frame `road`)");
        if let Some(wait) = self.foxglove_wait {
            if live.server().wait_for_subscriber(SCENE_TOPIC, wait) {
                println!("live view: a viewer subscribed to {SCENE_TOPIC}");
            } else {
                println!(
                    "live view: no viewer after {}; starting",
                    humantime::format_duration(wait)
                );
            }
        }
        Ok(Some(live))
    }
}

/// `sim_client campaign`.
#[derive(Args)]
pub struct CampaignArgs {
    /// Multiply every trial count by this (at least 1 trial per configuration).
    #[arg(long, default_value_t = 1.0)]
    trials_scale: f64,
    /// Custom configurations (TOML `[[config]]` tables or a JSON list) instead of Table I.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Base seed.
    #[arg(long, default_value_t = 2026)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Also run the paper-literal preset, the planner without hysteresis and the IDM +
    /// MOBIL ego.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    baselines: bool,
    /// With the baselines, also run the paper-literal preset (`false`: the planner, the
    /// planner without hysteresis and the IDM + MOBIL ego only).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    paper_literal: bool,
    #[command(flatten)]
    paper: PaperArgs,
    /// Probability that an SV keeps its longitudinal maneuver at each decision instant
    /// (0.4 s); otherwise it switches at random, as its HMDP allows (formulation.md: 0.8).
    /// 1: SVs change speed only as their IDM asks (docs/paper-literal.md, "The band against
    /// the rest, and calmer traffic").
    #[arg(long, value_name = "P", default_value_t = SvBehaviour::default().p_keep_long)]
    sv_keep_long: f64,
    /// Probability that an SV tries a random lane change at each decision instant, besides
    /// MOBIL's (0: MOBIL's only).
    #[arg(long, value_name = "P", default_value_t = SvBehaviour::default().p_random_lane_change)]
    sv_lane_change: f64,
    /// Deceleration of an SV in its slowdown mode (beta = -1), m/s^2, positive
    /// (formulation.md: 1). Harder slowdowns are traffic the planner's prediction was not
    /// tuned on.
    #[arg(long, value_name = "M/S2", default_value_t = SvBehaviour::default().gentle_decel)]
    sv_slowdown_decel: f64,
    /// Record the first `--record-trials` trials of every configuration, for every driver,
    /// into this directory (`config03-trial0-planner.mcap`, ...; docs/recording.md). They are
    /// run again after the campaign with the same seeds.
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// Trials recorded per configuration and driver (with `--record`).
    #[arg(long, default_value_t = 1, requires = "record")]
    record_trials: u32,
    /// Also write `campaign/hard-braking.jsonl`: every decision of the "planner" driver whose
    /// first step brakes at 2.5 m/s^2 or harder, with its situation: the input of `decision`'s
    /// `explain_decision` example (with this run's `--planner-config`, if any, as its second
    /// argument). See docs/safety-metrics.md.
    #[arg(long)]
    trace_hard_braking: bool,
}

pub fn run_campaign(common: &Common, args: &CampaignArgs) -> Result<()> {
    let CampaignArgs {
        trials_scale: scale,
        config,
        seed,
        threads,
        baselines,
        paper_literal,
        paper,
        sv_keep_long,
        sv_lane_change,
        sv_slowdown_decel,
        record,
        record_trials,
        trace_hard_braking,
    } = args;
    let (scale, seed, baselines, threads) = (*scale, *seed, *baselines, *threads);
    if common.transport != TransportKind::Inproc && baselines {
        // A planner process has one configuration; the no-hysteresis baseline needs another.
        anyhow::bail!("with a remote transport, run the campaign with --baselines false");
    }
    let sv = SvBehaviour {
        p_keep_long: *sv_keep_long,
        p_random_lane_change: *sv_lane_change,
        gentle_decel: *sv_slowdown_decel,
    };
    // Checked with the simulation's other parameters (a slowdown no harder than the vehicles
    // can brake) before anything is opened.
    traffic::SimParams {
        sv,
        ..traffic::SimParams::default()
    }
    .validate()?;
    let (transport, _planner) = common.open(None)?;
    let entries = match &config {
        Some(p) => campaign::load_entries(p)?,
        None => campaign::paper_entries(),
    };
    let entries = campaign::scale_trials(&entries, scale)?;
    let threads = threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let mut settings = CampaignSettings::new(entries, seed, threads);
    settings.baselines = baselines;
    settings.planner = common.planner_config()?;
    settings.paper_literal = if baselines && *paper_literal {
        Some(paper.config()?)
    } else {
        None
    };
    settings.transport = transport;
    settings.trace_hard_braking = *trace_hard_braking;
    settings.params.sv = sv;
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(settings.episode_count() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} episodes, eta {eta}")
            .expect("valid template"),
    );
    let results = campaign::run_campaign(&settings, &|| bar.inc(1))?;
    bar.finish_and_clear();
    let files = report::write_campaign(&common.out, &results)?;
    for g in &results.overall {
        let share = |v: Option<f64>| v.map_or("-".into(), |v| format!("{:.2}%", 100.0 * v));
        println!(
            "{:<22} trials {:>5}  decisions {:>7}  collision rate {:.2}%  NOR {}  GSRR {}  FBR {}  solve mean {:.3} ms p99 {:.3} ms max {:.3} ms",
            g.driver.name(),
            g.trials,
            g.decisions,
            100.0 * g.collision_rate,
            share(g.nor),
            share(g.gsrr),
            share(g.fbr),
            g.solve_time.mean_ms,
            g.solve_time.p99_ms,
            g.solve_time.max_ms,
        );
        let s = &g.safety;
        println!(
            "{:<22} collisions at fault {} / hit in lane {} / SV-SV {}  hard brakes {:.1}/h  min TTC p5 {} p50 {} s  TTC<3s {:.2}%  headway<1s {:.2}%  max DRAC {:.2} m/s^2",
            "",
            g.collision_split.ego_at_fault,
            g.collision_split.ego_hit_in_lane,
            g.collision_split.sv_sv,
            s.hard_braking_per_hour,
            s.min_ttc_p5_s.map_or("inf".into(), |v| format!("{v:.2}")),
            s.min_ttc_p50_s.map_or("inf".into(), |v| format!("{v:.2}")),
            100.0 * s.ttc_below_3s_share,
            100.0 * s.headway_below_1s_share,
            s.max_drac_mps2,
        );
    }
    println!(
        "campaign wall time {:.1} s on {} thread(s)",
        results.wall_time_s, results.threads
    );
    print_files(&files);
    if let Some(dir) = record {
        let files = recorded::record_campaign_trials(&settings, dir, *record_trials)?;
        println!(
            "  recorded {} trial(s) ({} per configuration and driver) in {}",
            files.len(),
            record_trials,
            dir.display()
        );
    }
    Ok(())
}

pub fn run_case1(common: &Common, seed: u64, paper: &PaperArgs, record: Option<&Path>, live: &LiveArgs) -> Result<()> {
    let (transport, _planner) = common.open(None)?;
    let config = common.planner_config()?;
    let info = recorded::trial_info("case1", &cases::case1_spec(seed, config.perception.max_svs));
    let mut live = live.start(info)?;
    let mut nobody = ();
    let observer: &mut dyn StepObserver = match live.as_mut() {
        Some(live) => live,
        None => &mut nobody,
    };
    let (planner, recorded) = match record {
        Some(path) => recorded::record_case_observed("case1", &config, &transport, seed, path, observer)?,
        None => (
            cases::run_case_observed(&config, &transport, seed, observer)?,
            Vec::new(),
        ),
    };
    if let Some(live) = live {
        let c = live.finish();
        println!("live view: {} messages published, {} dropped", c.published, c.dropped);
    }
    let paper_literal = Some(cases::run_case(&paper.config()?, &Transport::InProcess, seed)?);
    let case = cases::Case1 { planner, paper_literal };
    print_recorded(&recorded);
    let files = report::write_case1(&common.out, &case)?;
    println!("case1: {}", report::episode_summary_line(&case.planner.metrics));
    if let Some(p) = &case.paper_literal {
        println!("case1 paper_literal: {}", report::episode_summary_line(&p.metrics));
    }
    print_files(&files);
    Ok(())
}

pub fn run_case2(common: &Common, seed: u64, paper: &PaperArgs, record: Option<&Path>) -> Result<()> {
    if common.transport != TransportKind::Inproc {
        // A planner process has one configuration; the ablation needs two.
        anyhow::bail!("case2 runs the planner with and without hysteresis: use --transport inproc");
    }
    // Refuses the remote-transport flags, which mean nothing in process.
    let (transport, _none) = common.open(None)?;
    let (config, paper) = (common.planner_config()?, paper.config()?);
    let case = match record {
        Some(base) => {
            let (case, files) = recorded::record_case2(&config, Some(&paper), &transport, seed, base)?;
            print_recorded(&files);
            case
        }
        None => cases::run_case2(&config, Some(&paper), &transport, seed)?,
    };
    let files = report::write_case2(&common.out, &case)?;
    let s = case.summary();
    let runs = std::iter::once(("case2", &s.planner)).chain(s.paper_literal.iter().map(|a| ("case2 paper_literal", a)));
    for (name, a) in runs {
        println!(
            "{name}: beta switches with hysteresis {}, without {} (paper: 1 vs 33); collisions {} / {}",
            a.beta_switches_with,
            a.beta_switches_without,
            a.with_hysteresis.collisions,
            a.without_hysteresis.collisions
        );
        println!(
            "  with hysteresis: {}",
            report::episode_summary_line(&a.with_hysteresis)
        );
        println!(
            "  without hysteresis: {}",
            report::episode_summary_line(&a.without_hysteresis)
        );
    }
    print_files(&files);
    Ok(())
}

/// Prints the recordings written.
fn print_recorded(files: &[PathBuf]) {
    for f in files {
        println!("  recorded {}", f.display());
    }
}
