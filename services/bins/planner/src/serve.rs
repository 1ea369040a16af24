//! `planner serve`: the service with its front ends until SIGINT or SIGTERM.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use hmdp_ros2::MarkersFor;
use planner_service::config_file::ServiceSection;
use planner_service::{RateLimit, Service, ServiceConfig, QUEUE_PER_WORKER};
use protocol::ResponseSigner;
use tokio::sync::oneshot;
use transport::iceoryx2::{ServerOptions, WaitMode};

mod observe;

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Planner configuration (TOML); built-in defaults when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Serve over iceoryx2 shared memory (request-response `hmdp/planner/plan`).
    #[arg(long)]
    iceoryx2: bool,
    /// Serve as a ROS 2 node (`hmdp_planner`: service `/hmdp/plan`, topics `/hmdp/decisions`
    /// and `/hmdp/plan_markers`) on the domain `ROS_DOMAIN_ID` names (default 0); discovery
    /// follows `ROS_AUTOMATIC_DISCOVERY_RANGE`. See docs/ros2.md.
    #[arg(long)]
    ros2: bool,
    /// The ROS 2 node's name.
    #[arg(long, value_name = "NAME", default_value = hmdp_ros2::DEFAULT_SERVER_NODE, requires = "ros2")]
    ros2_node: String,
    /// Whose answers get RViz markers on `/hmdp/plan_markers`: `all`, `none`, or one vehicle
    /// id (with several vehicles each array replaces the last). Built only while a marker
    /// subscriber is discovered.
    #[arg(long, value_name = "all|none|ID", default_value = "all", value_parser = parse_markers, requires = "ros2")]
    ros2_markers: MarkersFor,
    /// iceoryx2 shared-memory file prefix; clients must use the same (default: iceoryx2's).
    #[arg(long, value_name = "PREFIX", requires = "iceoryx2")]
    iceoryx2_prefix: Option<String>,
    /// iceoryx2 clients (vehicles) that may be connected at once.
    #[arg(long, default_value_t = 64, requires = "iceoryx2")]
    iceoryx2_max_clients: usize,
    /// Latency mode: the iceoryx2 server thread spins (busy polls) for requests instead of
    /// sleeping on the request event, going back to the event after `--busy-poll-window`
    /// without a request. Costs a core while vehicles send.
    #[arg(long, requires = "iceoryx2")]
    busy_poll: bool,
    /// How long the server keeps spinning after the last request, e.g. `500ms`.
    #[arg(long, value_parser = humantime::parse_duration, default_value = "1s", requires = "busy_poll")]
    busy_poll_window: std::time::Duration,
    /// Zenoh configuration file (JSON5, as zenohd's), e.g. deploy/zenoh/planner.json5;
    /// --zenoh-listen / --zenoh-connect replace its endpoints.
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable).
    #[arg(long = "zenoh-listen", value_name = "ENDPOINT")]
    zenoh_listen: Vec<String>,
    /// Zenoh endpoint to connect to, e.g. tcp/10.0.0.2:7447 (repeatable).
    #[arg(long = "zenoh-connect", value_name = "ENDPOINT")]
    zenoh_connect: Vec<String>,
    /// This instance's name among several planners on one Zenoh network (its queryable
    /// `hmdp/planner/plan/ID`, its liveliness token `hmdp/planner/alive/ID`); A-Z a-z 0-9 . _ -
    /// (default: host name and process id). See docs/deploy.md, "Scaling out".
    #[arg(long, value_name = "ID")]
    instance_id: Option<String>,
    /// Worker threads, each with its own planner (default: available cores).
    #[arg(long)]
    workers: Option<usize>,
    /// Requests that may wait for a worker; beyond that the fallback answers at once
    /// (default: 32 per worker).
    #[arg(long)]
    queue_capacity: Option<usize>,
    /// Record every request, every answer and the statistics to this MCAP file (see
    /// docs/recording.md); never delays an answer: records the writer cannot take are dropped
    /// and counted.
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
    /// Start a new file (FILE.1.mcap, ...) after this many MiB of messages.
    #[arg(long, value_name = "MIB", requires = "record")]
    record_rotate_mib: Option<u64>,
    /// Start a new file after this long, e.g. `1h`.
    #[arg(long, value_parser = humantime::parse_duration, requires = "record")]
    record_rotate_every: Option<Duration>,
    /// Serve a live view to Foxglove on this address (IP:PORT; without a value
    /// 127.0.0.1:8765): every request, answer and statistics document on the recording's
    /// topics and a 3D scene per answer (docs/live-view.md). Never delays an answer.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
    foxglove: Option<SocketAddr>,
    /// Queue places one vehicle id may hold; beyond that its requests get the fallback at once.
    #[arg(long, default_value_t = planner_service::QUEUE_PER_VEHICLE)]
    vehicle_queue: usize,
    /// Requests per second one vehicle id may send (also the burst); beyond that the fallback
    /// answers at once. 0 (the default): no limit; deployments set it (e.g. 50), simulations
    /// that run faster than real time must not.
    #[arg(long, default_value_t = 0.0)]
    vehicle_rate_limit: f64,
    /// Sign every answer with this Ed25519 key (`planner keygen`); replaces `[service]
    /// signing_key` of --config. Without a key answers are unsigned.
    #[arg(long, value_name = "FILE")]
    signing_key: Option<PathBuf>,
    /// How far vehicle and planner clocks may disagree: a request older than its deadline
    /// plus this (by its `sent_at_ns`) is answered as stale. Replaces `[service]
    /// clock_skew_tolerance_ms`; default 50ms.
    #[arg(long, value_parser = humantime::parse_duration)]
    clock_skew_tolerance: Option<Duration>,
    /// Nice value of the solver threads (0, the default: the process's own priority); above
    /// 0 the watchdog and the transports take the CPU before a solve does.
    #[arg(long, default_value_t = planner_service::WORKER_NICE, value_parser = clap::value_parser!(i32).range(0..=19))]
    worker_nice: i32,
    /// SCHED_FIFO priority of the deadline watchdog thread, 1-99 (0: an ordinary thread).
    /// Needs CAP_SYS_NICE or an RLIMIT_RTPRIO at least this high (systemd: LimitRTPRIO=);
    /// without, the watchdog stays an ordinary thread and a warning says so.
    #[arg(long, default_value_t = planner_service::WATCHDOG_RT_PRIORITY, value_parser = clap::value_parser!(i32).range(0..=99))]
    watchdog_rt_priority: i32,
    /// TEST ONLY: sleep this long before every solve, to force the watchdog.
    #[arg(long, default_value_t = 0, hide_short_help = true)]
    inject_solve_delay_ms: u64,
}

/// `--ros2-markers`: `all`, `none` or a vehicle id.
fn parse_markers(text: &str) -> Result<MarkersFor, String> {
    match text {
        "all" => Ok(MarkersFor::Everyone),
        "none" => Ok(MarkersFor::Nobody),
        id => id
            .parse()
            .map(MarkersFor::Vehicle)
            .map_err(|_| format!("`{id}` is not all, none or a vehicle id")),
    }
}

/// The service core's settings from the command line and the `[service]` table.
fn service_config(args: &ServeArgs, file: &ServiceSection) -> Result<ServiceConfig> {
    let mut config = ServiceConfig::default();
    if let Some(path) = args.signing_key.as_ref().or(file.signing_key.as_ref()) {
        let signer = ResponseSigner::from_file(path)?;
        tracing::info!(key = %path.display(), public_key = %signer.verifier().to_hex(), "signing answers");
        config.signer = Some(signer);
    } else {
        tracing::warn!("no signing key: answers are unsigned (docs/deploy.md, \"Signed answers\")");
    }
    if let Some(tolerance) = args.clock_skew_tolerance {
        config.clock_skew_tolerance = tolerance;
    } else if let Some(ms) = file.clock_skew_tolerance_ms {
        config.clock_skew_tolerance = Duration::from_millis(ms);
    }
    if let Some(w) = args.workers {
        config.workers = w.max(1);
        config.queue_capacity = QUEUE_PER_WORKER * config.workers;
    }
    if let Some(q) = args.queue_capacity {
        config.queue_capacity = q.max(1);
    }
    config.per_vehicle_queue = args.vehicle_queue.max(1);
    config.rate_limit = (args.vehicle_rate_limit > 0.0).then_some(RateLimit {
        per_second: args.vehicle_rate_limit,
        burst: args.vehicle_rate_limit.max(1.0),
    });
    config.worker_nice = args.worker_nice;
    config.watchdog_rt_priority = (args.watchdog_rt_priority > 0).then_some(args.watchdog_rt_priority);
    config.inject_solve_delay = Duration::from_millis(args.inject_solve_delay_ms);
    Ok(config)
}

/// The iceoryx2 server's settings from the command line.
fn iceoryx2_options(args: &ServeArgs) -> ServerOptions {
    ServerOptions {
        prefix: args.iceoryx2_prefix.clone(),
        max_clients: args.iceoryx2_max_clients,
        wait: if args.busy_poll {
            WaitMode::BusyPoll {
                window: args.busy_poll_window,
            }
        } else {
            WaitMode::Event
        },
        ..Default::default()
    }
}

/// The iceoryx2 front end on a thread of its own (its ports stay there) until `stop`; the
/// receiver resolves when it ends.
fn spawn_iceoryx2(
    service: Arc<Service>,
    options: ServerOptions,
    stop: Arc<AtomicBool>,
) -> Result<(JoinHandle<()>, oneshot::Receiver<Result<()>>)> {
    let (done_tx, done) = oneshot::channel::<Result<()>>();
    let thread = std::thread::Builder::new()
        .name("iceoryx2-server".into())
        .spawn(move || {
            let result = planner_service::iceoryx2_front::serve(service, &options, &stop).map_err(anyhow::Error::from);
            let _ = done_tx.send(result);
        })?;
    Ok((thread, done))
}

/// Runs the Zenoh front end (if configured) until a signal, or until a front end stops by
/// itself (which is an error: systemd then restarts the planner).
async fn run_until_stopped(
    service: Arc<Service>,
    zenoh_config: Option<(zenoh::Config, String)>,
    iceoryx2_done: Option<oneshot::Receiver<Result<()>>>,
) -> Result<()> {
    let (shutdown_tx, shutdown_rx) = oneshot::channel::<()>();
    let mut zenoh_task = zenoh_config.map(|(cfg, instance)| {
        tokio::spawn(planner_service::zenoh_front::serve(
            service,
            cfg,
            instance,
            async move {
                let _ = shutdown_rx.await;
            },
        ))
    });
    let iceoryx2_ended = async {
        match iceoryx2_done {
            Some(done) => done.await.unwrap_or(Ok(())),
            // No iceoryx2 front: never ends by itself.
            None => std::future::pending().await,
        }
    };
    let zenoh_ended = async {
        match zenoh_task.as_mut() {
            Some(task) => task.await,
            None => std::future::pending().await,
        }
    };
    let outcome = tokio::select! {
        _ = supervise::termination_signal() => Ok(()),
        ended = iceoryx2_ended => match ended {
            Ok(()) => Err(anyhow::anyhow!("the iceoryx2 front end stopped")),
            Err(e) => Err(e.context("iceoryx2 front end")),
        },
        ended = zenoh_ended => match ended {
            Ok(Ok(())) => Err(anyhow::anyhow!("the zenoh front end stopped")),
            Ok(Err(e)) => Err(anyhow::Error::new(e).context("zenoh front end")),
            Err(e) => Err(anyhow::anyhow!("the zenoh front end failed: {e}")),
        },
    };
    let _ = shutdown_tx.send(());
    if let Some(task) = zenoh_task {
        if !task.is_finished() {
            let _ = task.await;
        }
    }
    outcome
}

pub fn run(args: ServeArgs) -> Result<()> {
    let zenoh_wanted = !(args.zenoh_listen.is_empty() && args.zenoh_connect.is_empty() && args.zenoh_config.is_none());
    if !zenoh_wanted && !args.iceoryx2 && !args.ros2 {
        anyhow::bail!(
            "give --iceoryx2, --ros2 and/or a Zenoh transport (--zenoh-config FILE, --zenoh-listen or --zenoh-connect)"
        );
    }
    let (planner_config, service_file) = planner_service::config_file::planner_files(args.config.as_deref())?;
    let config = service_config(&args, &service_file)?;
    if !config.inject_solve_delay.is_zero() {
        tracing::warn!(ms = args.inject_solve_delay_ms, "TEST ONLY: injected solve delay");
    }
    let zenoh_config = if zenoh_wanted {
        let instance = args
            .instance_id
            .clone()
            .unwrap_or_else(transport::zenoh::instances::default_instance_id);
        transport::zenoh::instances::check_instance_id(&instance)?;
        // Without a file: a peer when it listens itself, else a client of the router it
        // connects to. Peers behind a router do not see each other's liveliness tokens
        // (Zenoh expects peers to mesh directly), and the instances must see each other to
        // share the vehicles of plain-key clients (docs/deploy.md, "Scaling out").
        let mode = if args.zenoh_listen.is_empty() {
            transport::zenoh::Mode::Client
        } else {
            transport::zenoh::Mode::Peer
        };
        let mut config = transport::zenoh::config(
            mode,
            args.zenoh_config.as_deref(),
            &args.zenoh_listen,
            &args.zenoh_connect,
        )?;
        if args.zenoh_config.is_none() && mode == transport::zenoh::Mode::Client {
            // As in the shipped planner files, behind a router: the router drops a hung
            // planner after its short lease, so plain-key clients reach another instance;
            // and the session, which fails at once when its router is not up yet, waits for
            // it 30 s (then fails, so that systemd restarts the planner). A planner that
            // listens itself keeps the 3 s lease: its vehicles are connected to it alone,
            // and a shorter one would only drop their queries during a short stall.
            let settings = [
                ("transport/link/tx", transport::zenoh::planner_lease().to_string()),
                ("connect/timeout_ms", "30000".into()),
            ];
            for (key, value) in settings {
                config
                    .insert_json5(key, &value)
                    .map_err(|e| anyhow::anyhow!("zenoh configuration {key}: {e}"))?;
            }
        }
        Some((config, instance))
    } else {
        None
    };
    let mut config = config;
    let watching = observe::Watching::start(&args)?;
    config.observers = watching.observers();
    let service = Arc::new(Service::start(planner_config, config.clone())?);
    let stats_thread = watching.publish_stats(service.stats());
    tracing::info!(
        workers = config.workers,
        queue = config.queue_capacity,
        "service started"
    );
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("building the tokio runtime")?;
    // If the iceoryx2 thread ends (e.g. another planner already serves the prefix), the
    // whole process stops.
    let stop_iceoryx2 = Arc::new(AtomicBool::new(false));
    let (iceoryx2_thread, iceoryx2_done) = if args.iceoryx2 {
        let (thread, done) = spawn_iceoryx2(
            Arc::clone(&service),
            iceoryx2_options(&args),
            Arc::clone(&stop_iceoryx2),
        )?;
        (Some(thread), Some(done))
    } else {
        (None, None)
    };
    let ros2 = if args.ros2 {
        let options = hmdp_ros2::ServerOptions {
            node: hmdp_ros2::NodeConfig::named(args.ros2_node.clone()),
            markers: args.ros2_markers,
            ..Default::default()
        };
        let server = planner_service::ros2_front::serve(Arc::clone(&service), options).context("ROS 2 front end")?;
        tracing::info!(node = %args.ros2_node, service = hmdp_ros2::SERVICE_NAME, "planner serving over ROS 2");
        Some(server)
    } else {
        None
    };
    let result = runtime.block_on(run_until_stopped(Arc::clone(&service), zenoh_config, iceoryx2_done));
    if let Some(server) = ros2 {
        server.stop();
    }
    stop_iceoryx2.store(true, Ordering::Relaxed);
    if let Some(t) = iceoryx2_thread {
        let _ = t.join();
    }
    drop(runtime);
    // Stop the workers first (they answer what is still queued), so that the final
    // statistics count every answer.
    let stats = service.stats();
    drop(service);
    // The observers' last handles are in `watching`: `finish` stops them.
    drop(config);
    let snapshot = stats.snapshot();
    tracing::info!(stats = %serde_json::to_string(&snapshot).unwrap_or_default(), "final statistics");
    watching.finish(stats_thread, &snapshot)?;
    result
}
