//! `sim_client`: runs the paper's experiments against the planner.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Result;
use clap::{Args, Parser, Subcommand, ValueEnum};
use protocol::ResponseVerifier;
use sim_client::connect::BUSY_POLL_WINDOW;
use sim_client::planner_process::{spawn_planner, Serve, SpawnOptions, SpawnedPlanner};
use sim_client::{Transport, ZenohTarget};
use transport::iceoryx2::WaitMode;

use compare_command::CompareArgs;
use load_command::{LoadArgs, LoadWorkerArgs};
use study_commands::{CampaignArgs, LiveArgs, PaperArgs};

mod compare_command;
mod load_command;
mod replay_command;
mod study_commands;

#[derive(Parser)]
#[command(
    name = "sim_client",
    version,
    about = "Closed-loop experiments of the HMDP-MPC planner (paper section IV)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The transport named on the command line (its target comes from the other flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum TransportKind {
    /// The planner in the same thread.
    Inproc,
    /// A `planner serve --iceoryx2` process on this machine.
    Iceoryx2,
    /// A `planner serve` process reached with `--zenoh-connect` or `--zenoh-config`.
    Zenoh,
    /// A `planner serve --ros2` node on the ROS 2 domain `ROS_DOMAIN_ID` names (docs/ros2.md).
    Ros2,
}

#[derive(Args)]
struct Common {
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Planner configuration (TOML); defaults when absent. With a remote transport it is
    /// used for the vehicle's own fallback, and passed to a planner started with
    /// `--spawn-planner`.
    #[arg(long, value_name = "FILE")]
    planner_config: Option<PathBuf>,
    /// How the planner is reached.
    #[arg(long, value_enum, default_value = "inproc")]
    transport: TransportKind,
    /// Zenoh endpoint of the planner service, e.g. tcp/127.0.0.1:7447 (with `--transport zenoh`).
    #[arg(long, value_name = "ENDPOINT")]
    zenoh_connect: Option<String>,
    /// Zenoh configuration file (JSON5), e.g. deploy/zenoh/client.json5 (with `--transport zenoh`).
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// With several planner instances: without an answer from the vehicle's instance this
    /// long, ask the next one (once); see docs/deploy.md, "Scaling out".
    #[arg(long, value_name = "D", value_parser = humantime::parse_duration, default_value = "150ms")]
    zenoh_retry_after: std::time::Duration,
    /// How long an instance that left a request unanswered is tried last.
    #[arg(long, value_name = "D", value_parser = humantime::parse_duration, default_value = "2s")]
    zenoh_suspect_for: std::time::Duration,
    /// iceoryx2 shared-memory prefix of the planner (with `--transport iceoryx2`).
    #[arg(long, value_name = "PREFIX")]
    iceoryx2_prefix: Option<String>,
    /// Latency mode (with `--transport iceoryx2`): the vehicles spin for their answers instead
    /// of sleeping on the response event; a planner started with `--spawn-planner` spins too.
    #[arg(long)]
    busy_poll: bool,
    /// Start `planner serve` (found next to this executable) for the run and stop it at exit
    /// (with `--transport zenoh` on a free loopback port, `--transport iceoryx2` under a
    /// prefix of its own, `--transport ros2` as a node on this process's ROS 2 domain).
    #[arg(long)]
    spawn_planner: bool,
    /// Where a planner started with `--spawn-planner` writes its log (default: this stderr).
    #[arg(long, value_name = "FILE", requires = "spawn_planner")]
    planner_log: Option<PathBuf>,
    /// A planner started with `--spawn-planner` records every request and answer to this
    /// MCAP file (`planner serve --record`; complete when the run ends and the planner stops).
    #[arg(long, value_name = "FILE.mcap", requires = "spawn_planner")]
    planner_record: Option<PathBuf>,
    /// The planner's public key (`planner keygen`'s `.pub` file): answers that do not verify
    /// (forged, altered, unsigned) are refused and counted; without it every answer is taken.
    #[arg(long, value_name = "FILE")]
    planner_key: Option<PathBuf>,
    /// The same key as 64 hex digits (how `load` hands it to its worker processes).
    #[arg(long, value_name = "HEX", hide = true, conflicts_with = "planner_key")]
    planner_public_key: Option<String>,
    /// Over Zenoh without a planner key, reach a planner beyond this host anyway (refused
    /// otherwise: any peer there could answer and be believed). Logged as INSECURE.
    #[arg(long)]
    insecure: bool,
}

impl Common {
    fn planner_config(&self) -> Result<decision::PlannerConfig> {
        Ok(planner_service::config_file::planner_config(
            self.planner_config.as_deref(),
        )?)
    }

    /// The planner's public key, when given.
    fn verifier(&self) -> Result<Option<ResponseVerifier>> {
        if let Some(path) = &self.planner_key {
            return Ok(Some(ResponseVerifier::from_file(path)?));
        }
        self.planner_public_key
            .as_deref()
            .map(|hex| {
                protocol::parse_hex(hex)
                    .and_then(|bytes| ResponseVerifier::from_bytes(&bytes))
                    .ok_or_else(|| anyhow::anyhow!("--planner-public-key is not an Ed25519 public key"))
            })
            .transpose()
    }

    /// Checks that the flags fit the transport, starts the planner if asked to, and builds the
    /// transport. `workers` goes to a started planner.
    fn open(&self, workers: Option<usize>) -> Result<(Transport, Option<SpawnedPlanner>)> {
        let zenoh_flags = self.zenoh_connect.is_some() || self.zenoh_config.is_some();
        let spawn = |serve: Serve| {
            let options = SpawnOptions {
                workers,
                config: self.planner_config.clone(),
                log: self.planner_log.clone(),
                record: self.planner_record.clone(),
            };
            spawn_planner(&serve, &options)
        };
        let verifier = self.verifier()?;
        if verifier.is_some() && self.spawn_planner {
            // A spawned planner has no signing key: every answer would be refused.
            anyhow::bail!("--planner-key needs a planner started with --signing-key, not --spawn-planner");
        }
        match self.transport {
            TransportKind::Inproc => {
                if zenoh_flags
                    || self.iceoryx2_prefix.is_some()
                    || self.spawn_planner
                    || self.busy_poll
                    || verifier.is_some()
                {
                    anyhow::bail!(
                        "--zenoh-*, --iceoryx2-prefix, --busy-poll, --planner-key and --spawn-planner need --transport zenoh or iceoryx2"
                    );
                }
                Ok((Transport::InProcess, None))
            }
            TransportKind::Zenoh => {
                if self.iceoryx2_prefix.is_some() || self.busy_poll {
                    anyhow::bail!("--iceoryx2-prefix and --busy-poll need --transport iceoryx2");
                }
                let mut target = ZenohTarget {
                    endpoint: self.zenoh_connect.clone(),
                    config_file: self.zenoh_config.clone(),
                    verifier,
                    failover: transport::zenoh::Failover {
                        retry_after: self.zenoh_retry_after,
                        suspect_for: self.zenoh_suspect_for,
                    },
                    insecure: self.insecure,
                };
                let planner = match (zenoh_flags, self.spawn_planner) {
                    (true, true) => anyhow::bail!("give either --zenoh-connect / --zenoh-config or --spawn-planner"),
                    (false, false) => anyhow::bail!(
                        "--transport zenoh needs --zenoh-connect ENDPOINT, --zenoh-config FILE or --spawn-planner"
                    ),
                    (true, false) => None,
                    (false, true) => {
                        let planner = spawn(Serve::Zenoh)?;
                        target.endpoint = planner.zenoh_endpoint.clone();
                        Some(planner)
                    }
                };
                Ok((Transport::Zenoh(target), planner))
            }
            TransportKind::Ros2 => {
                if zenoh_flags || self.iceoryx2_prefix.is_some() || self.busy_poll {
                    anyhow::bail!("--zenoh-*, --iceoryx2-prefix and --busy-poll do not apply to --transport ros2");
                }
                let planner = if self.spawn_planner {
                    Some(spawn(Serve::Ros2)?)
                } else {
                    None
                };
                Ok((Transport::Ros2 { verifier }, planner))
            }
            TransportKind::Iceoryx2 => {
                if zenoh_flags {
                    anyhow::bail!("--zenoh-connect / --zenoh-config need --transport zenoh");
                }
                let mut prefix = self.iceoryx2_prefix.clone();
                let planner = if self.spawn_planner {
                    let planner = spawn(Serve::Iceoryx2 {
                        prefix: prefix.clone(),
                        busy_poll: self.busy_poll,
                    })?;
                    prefix = planner.iceoryx2_prefix.clone();
                    Some(planner)
                } else {
                    None
                };
                let wait = if self.busy_poll {
                    WaitMode::BusyPoll {
                        window: BUSY_POLL_WINDOW,
                    }
                } else {
                    WaitMode::Event
                };
                Ok((Transport::Iceoryx2 { prefix, wait, verifier }, planner))
            }
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Latency under load: vehicle clients at a fixed rate against a planner process, each
    /// driving its own simulation; HDR percentiles of round trip, queueing and solve time,
    /// answers by layer, deadline misses, lost and duplicated answers, planner CPU and RSS.
    Load(LoadArgs),
    /// `load` for a long time (default 1 h), failing (exit 1) unless every request got
    /// exactly one answer by its deadline and the planner's RSS stayed flat.
    Soak {
        #[command(flatten)]
        load: LoadArgs,
        /// Largest allowed planner RSS growth after the warm-up, %.
        #[arg(long, default_value_t = 5.0)]
        max_rss_growth: f64,
    },
    /// One process's share of `load --processes` (writes its measurements as JSON).
    #[command(hide = true)]
    LoadWorker(LoadWorkerArgs),
    /// Case 1: the Table II scene for 40 s with the planner, and with the paper-literal
    /// preset (in process) beside it.
    Case1 {
        #[command(flatten)]
        common: Common,
        /// Seed of the simulator's random stream.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        paper: PaperArgs,
        /// Record the planner's trial (ground truth, decisions, a Foxglove scene) to this
        /// MCAP file (docs/recording.md).
        #[arg(long, value_name = "FILE.mcap")]
        record: Option<PathBuf>,
        #[command(flatten)]
        live: LiveArgs,
    },
    /// Log replay: the SVs of a recording follow their recorded trajectories, the ego is
    /// re-planned from its recorded start; scored like a campaign trial.
    Replay {
        #[command(flatten)]
        common: Common,
        #[command(flatten)]
        replay: replay_command::ReplayArgs,
    },
    /// Case 2: Case 1 with hysteresis on and off, for the planner and the paper-literal preset.
    Case2 {
        #[command(flatten)]
        common: Common,
        /// Seed of the simulator's random stream.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[command(flatten)]
        paper: PaperArgs,
        /// Record each run (ground truth, decisions, a Foxglove scene) next to this file:
        /// `FILE.with_hysteresis.mcap`, `FILE.without_hysteresis.mcap` and the same with
        /// `paper_literal.` for the preset (docs/recording.md).
        #[arg(long, value_name = "FILE.mcap")]
        record: Option<PathBuf>,
    },
    /// Case 3: the randomized campaign of Table I.
    Campaign {
        #[command(flatten)]
        common: Common,
        #[command(flatten)]
        campaign: CampaignArgs,
    },
    /// Two campaign runs of the same seed, paired trial by trial: every headline figure's
    /// difference with a bootstrap interval (docs/safety-metrics.md, "Comparing two runs").
    Compare(CompareArgs),
}

fn print_files(files: &[PathBuf]) {
    for f in files {
        println!("  wrote {}", f.display());
    }
}

fn main() -> Result<()> {
    supervise::init_process(&format!("warn,{}", hmdp_ros2::QUIET_LOG_DIRECTIVES));
    let cli = Cli::parse();
    let started = Instant::now();
    let mut exit_code = None;
    match cli.command {
        Command::Load(args) => {
            load_command::run_load_command(args, Duration::from_secs(30), false)?;
        }
        Command::Soak { load, max_rss_growth } => {
            let report = load_command::run_load_command(load, Duration::from_secs(3600), true)?;
            let violations = report.soak_violations(max_rss_growth);
            if violations.is_empty() {
                println!("soak: PASS (every request answered exactly once by its deadline; planner RSS flat)");
            } else {
                for v in &violations {
                    println!("soak: FAIL: {v}");
                }
                exit_code = Some(1);
            }
        }
        Command::LoadWorker(args) => return load_command::run_load_worker(args),
        Command::Case1 {
            common,
            seed,
            paper,
            record,
            live,
        } => study_commands::run_case1(&common, seed, &paper, record.as_deref(), &live)?,
        Command::Replay { common, replay } => {
            let (transport, _planner) = common.open(None)?;
            replay_command::run_replay(&replay, &transport, &common.planner_config()?)?;
        }
        Command::Case2 {
            common,
            seed,
            paper,
            record,
        } => study_commands::run_case2(&common, seed, &paper, record.as_deref())?,
        Command::Campaign { common, campaign } => study_commands::run_campaign(&common, &campaign)?,
        Command::Compare(args) => compare_command::run_compare(&args)?,
    }
    println!("wall time {:.2} s", started.elapsed().as_secs_f64());
    if let Some(code) = exit_code {
        std::process::exit(code);
    }
    Ok(())
}
