//! iceoryx2 vehicles killed (SIGKILL) with requests in flight, then new vehicles: every answer
//! a new vehicle receives is its own.
//!
//! The planner answers a request through the connection it arrived on; a killed client's
//! connection slot is given to the next client that opens the service, and its late answers
//! must not follow. Each round starts `sim_client load` processes against a planner slow
//! enough that they always have requests in flight, kills them all at once and at once
//! connects new vehicles: in this process, with vehicle ids of their own, so that an answer
//! meant for a killed vehicle would show, counting every answer that reached them for another
//! request, even one the client discarded; and a `sim_client load` process with the killed
//! tools' vehicle ids (1, 2, ...), whose report must count no mismatched answer and whose log
//! no discarded one.

use std::process::Command;
use std::time::{Duration, Instant};

use protocol::PlanRequest;
use system_tests::{binary, scratch_dir, worked_example_request, Iceoryx2Prefix, Process};
use transport::iceoryx2::{Client, ClientOptions};

/// Kill rounds; each kills [`TOOLS`] load processes of [`TOOL_VEHICLES`] vehicles.
const ROUNDS: u64 = 4;
const TOOLS: usize = 3;
const TOOL_VEHICLES: &str = "4";
/// New vehicles connected right after each round's kill, and their requests.
const NEWCOMERS: u64 = 4;
const NEWCOMER_REQUESTS: u64 = 12;

/// What the new vehicles got.
#[derive(Debug, Default)]
struct Figures {
    sent: u64,
    /// Answered with the request's own vehicle id and sequence.
    answered: u64,
    /// Answers that reached a new vehicle for a request it did not send (the client
    /// discards them; any is a failure).
    foreign: u64,
    /// Answers beyond the first.
    extra: u64,
}

impl std::ops::AddAssign for Figures {
    fn add_assign(&mut self, o: Self) {
        self.sent += o.sent;
        self.answered += o.answered;
        self.foreign += o.foreign;
        self.extra += o.extra;
    }
}

fn connect(prefix: &str, name: &str) -> Client {
    let options = ClientOptions {
        prefix: Some(prefix.to_string()),
        ready_timeout: Duration::from_secs(60),
        node_name: name.to_string(),
        ..ClientOptions::default()
    };
    Client::connect(&options).expect("the planner's iceoryx2 services")
}

/// One new vehicle: connects (a new node, which removes the killed ones' resources), probes
/// until served, then sends `NEWCOMER_REQUESTS` requests one after the other.
fn newcomer(prefix: &str, vehicle_id: u64) -> Figures {
    let mut client = connect(prefix, &format!("newcomer-{vehicle_id}"));
    let mut figures = Figures::default();
    let give_up = Instant::now() + Duration::from_secs(60);
    loop {
        let probe = client
            .request(PlanRequest::probe(vehicle_id), Duration::from_millis(500))
            .unwrap();
        figures.foreign += probe.mismatched as u64;
        if probe.response.is_some() {
            break;
        }
        assert!(
            Instant::now() < give_up,
            "vehicle {vehicle_id}: the planner never answered"
        );
    }
    for sequence in 1..=NEWCOMER_REQUESTS {
        let exchange = client
            .request(worked_example_request(vehicle_id, sequence), Duration::from_secs(2))
            .unwrap();
        figures.sent += 1;
        figures.foreign += exchange.mismatched as u64;
        figures.extra += exchange.extra_responses as u64;
        if let Some(r) = exchange.response {
            assert_eq!(
                (r.vehicle_id, r.sequence),
                (vehicle_id, sequence),
                "taken as the answer"
            );
            figures.answered += 1;
        }
    }
    figures
}

/// What a clean `sim_client load` run reported: answers it took for another request, and
/// answers its vehicles' clients discarded as not theirs (reported and logged).
fn clean_load_run(prefix: &str, dir: &std::path::Path) -> (u64, usize, String) {
    let json = dir.join("report.json");
    let out = Command::new(binary("sim_client"))
        .args(["load", "--transport", "iceoryx2", "--iceoryx2-prefix", prefix])
        .args(["--clients", TOOL_VEHICLES, "--rate", "10", "--duration", "4s", "--out"])
        .arg(dir)
        .arg("--json")
        .arg(&json)
        .output()
        .expect("sim_client runs");
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "clean load run:\n{log}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("report")).expect("a JSON report");
    let mismatched = report["counts"]["mismatched"].as_u64().expect("counts.mismatched");
    // The report counts what the clients discarded; each discard is also logged.
    let discarded = report["counts"]["discarded"].as_u64().expect("counts.discarded");
    let logged = log.lines().filter(|l| l.contains(": ignored")).count();
    assert_eq!(discarded, logged as u64, "discards reported and logged differ:\n{log}");
    (mismatched, discarded as usize, log)
}

/// `sim_client load` over iceoryx2 as a process, until killed.
fn load_tool(prefix: &str, dir: &std::path::Path, tag: &str) -> Process {
    let out = dir.join(tag);
    Process::start(
        "sim_client",
        &[
            "load",
            "--transport",
            "iceoryx2",
            "--iceoryx2-prefix",
            prefix,
            "--clients",
            TOOL_VEHICLES,
            "--rate",
            "20",
            "--duration",
            "120s",
            "--out",
            out.to_str().unwrap(),
        ],
        tag,
    )
}

#[test]
fn answers_never_reach_another_vehicle_after_vehicles_were_killed_mid_request() {
    let files = Iceoryx2Prefix::new("killed");
    let prefix = files.as_str().to_string();
    let dir = scratch_dir("killed");
    // One slow worker: the load tools always have requests queued or being solved (most
    // answered by the watchdog at the deadline), so each kill leaves answers to come.
    let planner = Process::start(
        "planner",
        &[
            "serve",
            "--iceoryx2",
            "--iceoryx2-prefix",
            &prefix,
            "--workers",
            "1",
            "--inject-solve-delay-ms",
            "40",
        ],
        "killed-planner",
    );
    let mut figures = Figures::default();
    let (mut load_mismatched, mut load_discarded) = (0, 0);
    for round in 0..ROUNDS {
        let mut tools: Vec<Process> = (0..TOOLS)
            .map(|i| load_tool(&prefix, &dir, &format!("killed-load-{round}-{i}")))
            .collect();
        // Time to connect their vehicles and have requests in flight.
        std::thread::sleep(Duration::from_millis(2000));
        for tool in &mut tools {
            assert!(tool.is_running(), "a load tool ended early:\n{}", tool.log());
            tool.kill();
        }
        let clean_dir = dir.join(format!("clean-{round}"));
        let (newcomers, (mismatched, discarded, log)) = std::thread::scope(|scope| {
            let prefix = &prefix;
            let vehicles: Vec<_> = (0..NEWCOMERS)
                .map(|i| scope.spawn(move || newcomer(prefix, 10_000 + round * 100 + i)))
                .collect();
            let load = scope.spawn(|| clean_load_run(prefix, &clean_dir));
            let mut sum = Figures::default();
            for v in vehicles {
                sum += v.join().expect("newcomer thread");
            }
            (sum, load.join().expect("clean load run"))
        });
        figures += newcomers;
        if mismatched + discarded as u64 > 0 {
            eprintln!(
                "round {round}: the clean load run took {mismatched} and discarded {discarded} foreign answers:\n{log}"
            );
        }
        load_mismatched += mismatched;
        load_discarded += discarded;
    }
    eprintln!(
        "after {ROUNDS} kill rounds: newcomers {figures:?}; clean load runs: {load_mismatched} mismatched, {load_discarded} discarded"
    );
    assert_eq!(
        (load_mismatched, load_discarded),
        (0, 0),
        "foreign answers reached the clean load runs"
    );
    assert_eq!(
        figures.foreign,
        0,
        "answers for killed vehicles reached new ones: {figures:?}\n{}",
        planner.log()
    );
    assert_eq!(figures.extra, 0, "{figures:?}");
    assert_eq!(figures.sent, ROUNDS * NEWCOMERS * NEWCOMER_REQUESTS);
    assert_eq!(figures.answered, figures.sent, "{figures:?}\n{}", planner.log());
}
