//! Where an iceoryx2 round trip's time goes, leg by leg, in one process: the planner's
//! iceoryx2 server (`transport::iceoryx2::serve`) whose "planner" answers from a worker pool
//! after a simulated solve (a spin, which holds a core as a real solve does), and vehicles on
//! client threads sending paced requests through `transport::iceoryx2::Client`. One process
//! means one clock: every leg is measured, not inferred.
//!
//! ```sh
//! cargo run --release -p transport --example iceoryx2_roundtrip -- --clients 8 --rate 2.5 --duration 30 --busy-poll
//! ```
//!
//! Options: `--clients K` (8), `--rate HZ` per client (2.5), `--duration S` (30),
//! `--solve-us US` simulated solve (200), `--workers N` (1), `--busy-poll` (both sides spin;
//! default: both sleep on their events), `--inline` (the server thread answers itself, no
//! hand-over to a worker).
//!
//! Legs of one exchange (percentiles over all exchanges):
//! - `request`: the vehicle starts sending → the server thread has the request;
//! - `handover`: → a worker starts on it (0 with `--inline`);
//! - `solve`: the simulated solve;
//! - `respond`: the answer's write, send and the clients' wake-up notification;
//! - `response`: the answer is sent → the vehicle has it;
//! - `transport share`: round trip minus handover and solve (what `sim_client load` reports
//!   as the transport's share, whose planner-side queueing is the handover here).

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;
use protocol::{PlanResponse, RejectReason, Rejected};
use transport::iceoryx2::{serve, Client, ClientOptions, Responder, ServerOptions, WaitMode};

struct Options {
    clients: usize,
    rate_hz: f64,
    duration: Duration,
    solve: Duration,
    workers: usize,
    busy_poll: bool,
    inline: bool,
}

fn options() -> Options {
    let mut o = Options {
        clients: 8,
        rate_hz: 2.5,
        duration: Duration::from_secs(30),
        solve: Duration::from_micros(200),
        workers: 1,
        busy_poll: false,
        inline: false,
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
            "--busy-poll" => o.busy_poll = true,
            "--inline" => o.inline = true,
            other => panic!("unknown option {other}"),
        }
    }
    o
}

/// The server side's instants of one exchange, keyed by (vehicle, sequence).
#[derive(Clone, Copy)]
struct ServerSide {
    received: Instant,
    solve_start: Instant,
    solve_end: Instant,
    sent: Instant,
}

type Ledger = Arc<Mutex<HashMap<(u64, u64), ServerSide>>>;

fn spin_for(d: Duration) {
    let until = Instant::now() + d;
    while Instant::now() < until {
        std::hint::spin_loop();
    }
}

/// Solves (spins), answers, and writes the exchange's server-side instants to `ledger`.
fn answer(responder: Responder, received: Instant, solve: Duration, ledger: &Ledger) {
    let solve_start = Instant::now();
    spin_for(solve);
    let solve_end = Instant::now();
    let r = responder.request();
    let key = (r.vehicle_id, r.sequence);
    // Any answer will do: every `PlanResponse` occupies the same fixed-size slot in shared memory.
    let response = PlanResponse::rejected(r.vehicle_id, r.sequence, Rejected::new(RejectReason::Malformed, ""), 0);
    if let Err(e) = responder.respond(response) {
        eprintln!("answer {key:?} not sent: {e}");
        return;
    }
    let sent = Instant::now();
    let side = ServerSide {
        received,
        solve_start,
        solve_end,
        sent,
    };
    ledger.lock().unwrap().insert(key, side);
}

fn start_server(o: &Options, prefix: String, ledger: Ledger, shutdown: Arc<AtomicBool>) -> thread::JoinHandle<()> {
    let wait = if o.busy_poll {
        WaitMode::BusyPoll {
            window: Duration::from_secs(1),
        }
    } else {
        WaitMode::Event
    };
    let options = ServerOptions {
        prefix: Some(prefix),
        max_clients: o.clients.max(1),
        wait,
        ..ServerOptions::default()
    };
    let (solve, inline) = (o.solve, o.inline);
    let (jobs, queue) = mpsc::channel::<(Responder, Instant)>();
    let queue = Arc::new(Mutex::new(queue));
    for i in 0..o.workers {
        let (queue, ledger) = (Arc::clone(&queue), Arc::clone(&ledger));
        thread::Builder::new()
            .name(format!("worker-{i}"))
            .spawn(move || loop {
                let job = queue.lock().unwrap().recv();
                let Ok((responder, received)) = job else { return };
                answer(responder, received, solve, &ledger);
            })
            .expect("a worker");
    }
    thread::Builder::new()
        .name("iox2-server".into())
        .spawn(move || {
            serve(&options, &shutdown, |responder| {
                let received = Instant::now();
                if inline {
                    answer(responder, received, solve, &ledger);
                } else {
                    let _ = jobs.send((responder, received));
                }
            })
            .expect("the server runs");
        })
        .expect("the server thread")
}

/// One exchange as the vehicle saw it.
struct Sample {
    key: (u64, u64),
    sent: Instant,
    got: Instant,
}

fn vehicle(vehicle_id: u64, o: &Options, prefix: String, start: Instant) -> (Vec<Sample>, u64) {
    let wait = if o.busy_poll {
        WaitMode::BusyPoll {
            window: Duration::from_millis(50),
        }
    } else {
        WaitMode::Event
    };
    let mut client = Client::connect(&ClientOptions {
        prefix: Some(prefix),
        node_name: format!("bench-vehicle-{vehicle_id}"),
        wait,
        ..ClientOptions::default()
    })
    .expect("the client connects");
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
        let request = protocol::worked_example_request(vehicle_id, sequence);
        let sent = Instant::now();
        let exchange = client
            .request(request, Duration::from_millis(400))
            .expect("the exchange");
        let got = Instant::now();
        match exchange.response {
            Some(_) => samples.push(Sample {
                key: (vehicle_id, sequence),
                sent,
                got,
            }),
            None => lost += 1,
        }
    }
    (samples, lost)
}

fn histogram() -> Histogram<u64> {
    Histogram::new(3).expect("a histogram")
}

fn us(later: Instant, earlier: Instant) -> u64 {
    later.saturating_duration_since(earlier).as_micros() as u64
}

fn line(name: &str, h: &Histogram<u64>) {
    println!(
        "{name:<16} p50 {:>6} µs  p90 {:>6} µs  p99 {:>6} µs  max {:>6} µs",
        h.value_at_quantile(0.5),
        h.value_at_quantile(0.9),
        h.value_at_quantile(0.99),
        h.max()
    );
}

fn main() {
    let o = Arc::new(options());
    let files = supervise::ShmPrefix::unique("hmdpbench");
    let prefix = files.as_str().to_string();
    let ledger: Ledger = Arc::default();
    let shutdown = Arc::new(AtomicBool::new(false));
    let server = start_server(&o, prefix.clone(), Arc::clone(&ledger), Arc::clone(&shutdown));
    // Clients wait for the server's services; the first requests go out after every client
    // has connected.
    let start = Instant::now() + Duration::from_secs(2);
    let vehicles: Vec<_> = (0..o.clients as u64)
        .map(|v| {
            let (o, prefix) = (Arc::clone(&o), prefix.clone());
            thread::spawn(move || vehicle(v, &o, prefix, start))
        })
        .collect();
    let mut lost = 0;
    let mut samples = Vec::new();
    for v in vehicles {
        let (s, l) = v.join().expect("a vehicle");
        lost += l;
        samples.extend(s);
    }
    shutdown.store(true, std::sync::atomic::Ordering::Relaxed);
    server.join().expect("the server thread");

    let names = [
        "round trip",
        "request",
        "handover",
        "solve",
        "respond",
        "response",
        "transport share",
    ];
    let mut h: Vec<Histogram<u64>> = names.iter().map(|_| histogram()).collect();
    let ledger = ledger.lock().unwrap();
    for s in &samples {
        let Some(side) = ledger.get(&s.key) else { continue };
        let legs = [
            us(s.got, s.sent),
            us(side.received, s.sent),
            us(side.solve_start, side.received),
            us(side.solve_end, side.solve_start),
            us(side.sent, side.solve_end),
            us(s.got, side.sent),
            us(s.got, s.sent).saturating_sub(us(side.solve_end, side.received)),
        ];
        for (h, v) in h.iter_mut().zip(legs) {
            h.record(v).expect("in range");
        }
    }
    println!(
        "{} clients x {} Hz x {:?}, {} worker(s){}, simulated solve {:?}, {}",
        o.clients,
        o.rate_hz,
        o.duration,
        o.workers,
        if o.inline { " (answering inline)" } else { "" },
        o.solve,
        if o.busy_poll { "busy polling" } else { "event waiting" }
    );
    println!("answered {}  lost {lost}", samples.len());
    for (name, h) in names.iter().zip(&h) {
        line(name, h);
    }
}
