//! Round trips through the planner's ROS 2 service in one process: a `PlanServer` whose
//! "planner" answers from a worker pool (after an optional simulated solve), and vehicles on
//! client threads sending paced requests. Prints the round-trip percentiles and the
//! overhead: the round trip minus the server-side time between the request's arrival and
//! its reply (carried back in `queue_us` + `solve_us`).
//!
//! ```sh
//! cargo run --release -p hmdp_ros2 --example ros2_roundtrip -- --clients 8 --rate 2.5 --duration 60
//! ```
//!
//! Options: `--clients K` (8), `--rate HZ` per client (2.5), `--duration S` (60),
//! `--solve-us US` simulated solve (0), `--workers N` (2), `--separate-nodes` (a `PlanClient`,
//! hence a DDS participant, per client thread; default: one shared by all). Domain from
//! `ROS_DOMAIN_ID`; set `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` to stay on loopback. Logs
//! (RustDDS's too) with `RUST_LOG`, e.g. `RUST_LOG=hmdp_ros2=debug`.

use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use hmdp_ros2::{ClientOptions, Incoming, MarkersFor, NodeConfig, PlanClient, PlanServer, Reply, ServerOptions};
use protocol::{PlanResponse, RejectReason, Rejected};

struct Options {
    clients: usize,
    rate_hz: f64,
    duration: Duration,
    solve: Duration,
    workers: usize,
    separate_nodes: bool,
}

fn options() -> Options {
    let mut o = Options {
        clients: 8,
        rate_hz: 2.5,
        duration: Duration::from_secs(60),
        solve: Duration::ZERO,
        workers: 2,
        separate_nodes: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        match flag.as_str() {
            "--clients" => o.clients = value().parse().expect("a count"),
            "--rate" => o.rate_hz = value().parse().expect("Hz"),
            "--duration" => o.duration = Duration::from_secs_f64(value().parse().expect("seconds")),
            "--solve-us" => o.solve = Duration::from_micros(value().parse().expect("µs")),
            "--workers" => o.workers = value().parse().expect("a count"),
            "--separate-nodes" => o.separate_nodes = true,
            other => panic!("unknown option {other}"),
        }
    }
    o
}

/// A decision echoing the request, carrying the server-side time in `queue_us`.
fn answer(incoming: Incoming, arrival: Instant, solve: Duration) -> PlanResponse {
    if !solve.is_zero() {
        thread::sleep(solve);
    }
    let queue_us = u32::try_from(arrival.elapsed().as_micros()).unwrap_or(u32::MAX);
    match incoming {
        Incoming::Request(r) => {
            let decided = protocol::Decided::new(
                protocol::Action::default(),
                r.ego.maneuver,
                protocol::SetPoint {
                    accel_mps2: 0.0,
                    target_speed_mps: r.ego.v_mps,
                },
                Default::default(),
                protocol::Layer::Nominal,
                Default::default(),
            );
            PlanResponse::decided(r.vehicle_id, r.sequence, decided, 0, queue_us)
        }
        Incoming::Undecodable {
            vehicle_id, sequence, ..
        } => PlanResponse::rejected(
            vehicle_id,
            sequence,
            Rejected::new(RejectReason::Malformed, ""),
            queue_us,
        ),
    }
}

fn start_server(o: &Options) -> PlanServer {
    let (jobs, queue) = mpsc::channel::<(Incoming, Instant, Reply)>();
    let queue = Arc::new(Mutex::new(queue));
    for i in 0..o.workers {
        let (queue, solve) = (Arc::clone(&queue), o.solve);
        thread::Builder::new()
            .name(format!("worker-{i}"))
            .spawn(move || loop {
                let job = queue.lock().unwrap().recv();
                let Ok((incoming, arrival, reply)) = job else { return };
                reply(answer(incoming, arrival, solve));
            })
            .expect("a worker");
    }
    let jobs = Mutex::new(jobs);
    let options = ServerOptions {
        node: NodeConfig::named("hmdp_planner_bench"),
        markers: MarkersFor::Nobody,
        ..ServerOptions::default()
    };
    PlanServer::start(options, move |incoming, arrival, reply| {
        let _ = jobs.lock().unwrap().send((incoming, arrival, reply));
    })
    .expect("the server starts")
}

fn new_client(name: String) -> PlanClient {
    let client = PlanClient::new(ClientOptions {
        node: NodeConfig::named(name),
    })
    .expect("the client starts");
    client
        .wait_for_service(Duration::from_secs(20))
        .expect("the server is found");
    client
}

struct Sample {
    rtt_us: u64,
    server_us: u64,
}

fn vehicle(client: &PlanClient, vehicle_id: u64, o: &Options, start: Instant) -> (Vec<Sample>, u64) {
    let period = Duration::from_secs_f64(1.0 / o.rate_hz);
    // Spread the vehicles over one period, as unsynchronised vehicles are.
    let offset = period.mul_f64(vehicle_id as f64 / o.clients as f64);
    let (mut samples, mut lost) = (Vec::new(), 0);
    for sequence in 1.. {
        let due = start + offset + period * (sequence as u32 - 1);
        if due > start + o.duration {
            break;
        }
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            thread::sleep(wait);
        }
        let mut request = protocol::worked_example_request(vehicle_id, sequence);
        request.sent_at_ns = protocol::unix_now_ns();
        let sent = Instant::now();
        match client.exchange(&request, Duration::from_millis(400)) {
            Ok(Some(response)) => {
                let rtt_us = sent.elapsed().as_micros() as u64;
                let server_us = u64::from(response.queue_us) + u64::from(response.solve_us);
                samples.push(Sample { rtt_us, server_us });
            }
            Ok(None) => lost += 1,
            Err(e) => panic!("exchange failed: {e}"),
        }
    }
    (samples, lost)
}

fn line(name: &str, h: &Histogram<u64>) {
    println!(
        "{name:<9} p50 {:>6} µs  p90 {:>6} µs  p99 {:>6} µs  max {:>6} µs",
        h.value_at_quantile(0.5),
        h.value_at_quantile(0.9),
        h.value_at_quantile(0.99),
        h.max()
    );
}

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    let o = options();
    let server = start_server(&o);
    let shared = (!o.separate_nodes).then(|| Arc::new(new_client(format!("hmdp_bench_{}", std::process::id()))));
    let start = Instant::now() + Duration::from_millis(500);
    let o = Arc::new(o);
    let vehicles: Vec<_> = (0..o.clients as u64)
        .map(|v| {
            let (o, shared) = (Arc::clone(&o), shared.clone());
            thread::spawn(move || match shared {
                Some(client) => vehicle(&client, v, &o, start),
                None => vehicle(
                    &new_client(format!("hmdp_bench_{}_{v}", std::process::id())),
                    v,
                    &o,
                    start,
                ),
            })
        })
        .collect();
    let (mut rtt, mut overhead) = (Histogram::<u64>::new(3).unwrap(), Histogram::<u64>::new(3).unwrap());
    let mut lost = 0;
    for v in vehicles {
        let (samples, l) = v.join().expect("a vehicle");
        lost += l;
        for s in samples {
            rtt.record(s.rtt_us).unwrap();
            overhead.record(s.rtt_us.saturating_sub(s.server_us)).unwrap();
        }
    }
    println!(
        "{} clients x {} Hz x {:?} ({}), {} workers, simulated solve {:?}",
        o.clients,
        o.rate_hz,
        o.duration,
        if o.separate_nodes {
            "a node per client"
        } else {
            "one shared client node"
        },
        o.workers,
        o.solve
    );
    println!("answered {}  lost {lost}  server {:?}", rtt.len(), server.counters());
    line("round trip", &rtt);
    line("overhead", &overhead);
    server.stop();
}
