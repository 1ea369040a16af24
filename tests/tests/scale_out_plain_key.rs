//! Scale-out for clients that only know `hmdp/planner/plan`, as docs/protocol.md describes
//! it (a client in another language, a bridge): no liveliness tokens, no instance keys, the
//! default query target. A router (`hmdp-router`, loopback, a free port), two planners
//! `alpha` and `beta` connected to it, vehicles as plain Zenoh sessions of their own.
//!
//! Zenoh routes such a query to one complete queryable, and always the same one; the
//! planners share the vehicles among themselves (docs/deploy.md, "Scaling out"):
//!
//! * 16 vehicles, half of them querying with Zenoh's default consolidation and half with
//!   none: every request answered once, and each instance decides at least 30 % of them
//!   (by the planners' own final statistics);
//! * each instance in turn stopped with SIGSTOP for 3 s while 4 vehicles send at 10 Hz:
//!   every vehicle is answered while the instance still hangs (the longest gap between two
//!   answers is printed: the measurement docs/deploy.md reports).

use std::time::{Duration, Instant};

use protocol::{decode_bincode, encode_bincode, PlanResponse, ZENOH_PLAN_KEY};
use system_tests::instances::{RoutedPlanners, INSTANCES};
use system_tests::{signal, worked_example_request};
use transport::zenoh::instances::rendezvous_order;
use transport::zenoh::{client_config, encoding};
use zenoh::query::ConsolidationMode;
use zenoh::Wait;

/// What a vehicle waits for each answer (its deadline).
const DEADLINE: Duration = Duration::from_millis(400);

/// A vehicle that knows only the plain key: its own client session.
struct PlainVehicle {
    session: zenoh::Session,
    consolidation: ConsolidationMode,
}

impl PlainVehicle {
    fn connect(network: &RoutedPlanners, consolidation: ConsolidationMode) -> Self {
        let session = zenoh::open(client_config(&network.endpoint).unwrap())
            .wait()
            .expect("vehicle session");
        Self { session, consolidation }
    }

    /// One request on `hmdp/planner/plan`; its answers (decisions for this very request)
    /// within the deadline, and when the first came.
    fn ask(&self, vehicle: u64, sequence: u64) -> (usize, Option<Instant>) {
        let replies = self
            .session
            .get(ZENOH_PLAN_KEY)
            .payload(encode_bincode(&worked_example_request(vehicle, sequence)))
            .encoding(encoding(protocol::WireFormat::Bincode))
            .consolidation(self.consolidation)
            .timeout(DEADLINE)
            .wait()
            .expect("query sent");
        let (mut answers, mut first) = (0, None);
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let Ok(response) = decode_bincode::<PlanResponse>(&sample.payload().to_bytes()) else {
                continue;
            };
            if (response.vehicle_id, response.sequence) == (vehicle, sequence)
                && response.outcome.as_decided().is_some()
            {
                answers += 1;
                first.get_or_insert_with(Instant::now);
            }
        }
        (answers, first)
    }
}

fn count(stats: &serde_json::Value, field: &str) -> u64 {
    stats[field].as_u64().unwrap_or(0)
}

#[test]
fn plain_key_vehicles_are_shared_by_the_instances() {
    const VEHICLES: u64 = 16;
    const REQUESTS: u64 = 10;
    let mut network = RoutedPlanners::start("plain-share");
    // Until both instances serve and see each other.
    drop(network.vehicle(DEADLINE));
    let total = VEHICLES * REQUESTS;
    // Four sessions, four vehicle ids each; two with Zenoh's default consolidation (which
    // holds the answers until the query is over), two with none.
    let answers: Vec<usize> = std::thread::scope(|scope| {
        let threads: Vec<_> = (0..4u64)
            .map(|t| {
                let network = &network;
                scope.spawn(move || {
                    let mode = if t % 2 == 0 {
                        ConsolidationMode::Auto
                    } else {
                        ConsolidationMode::None
                    };
                    let vehicle = PlainVehicle::connect(network, mode);
                    let mut answers = Vec::new();
                    for sequence in 1..=REQUESTS {
                        for id in (1..=VEHICLES).filter(|v| v % 4 == t) {
                            answers.push(vehicle.ask(id, sequence).0);
                        }
                    }
                    answers
                })
            })
            .collect();
        threads
            .into_iter()
            .flat_map(|t| t.join().expect("vehicle thread"))
            .collect()
    });
    let stats = network.final_statistics();
    let answered: Vec<u64> = stats.iter().map(|s| count(s, "answered")).collect();
    let forwarded: Vec<u64> = stats.iter().map(|s| count(s, "forwarded")).collect();
    let taken_back: u64 = stats.iter().map(|s| count(s, "taken_back")).sum();
    eprintln!(
        "plain key, {VEHICLES} vehicles x {REQUESTS}: decided by {INSTANCES:?} {answered:?} of {total}, forwarded {forwarded:?}, taken back {taken_back}"
    );
    assert_eq!(answers.len() as u64, total);
    assert!(
        answers.iter().all(|a| *a == 1),
        "every request answered exactly once: {answers:?}\n{}",
        network.logs()
    );
    // A request taken back after a silent instance is decided by both.
    assert_eq!(answered.iter().sum::<u64>(), total + taken_back);
    for (id, n) in INSTANCES.iter().zip(&answered) {
        assert!(*n * 10 >= total * 3, "{id} decided {n} of {total}");
    }
}

/// Sends requests of `vehicle` at 10 Hz until `end`; when each answer came (`None`: none
/// within the deadline).
fn drive(vehicle: &PlainVehicle, id: u64, start: Instant, end: Duration) -> Vec<Option<Instant>> {
    let period = Duration::from_millis(100);
    let mut answers = Vec::new();
    for sequence in 1.. {
        let at = start + period * (sequence - 1);
        if at > start + end {
            break;
        }
        std::thread::sleep(at.saturating_duration_since(Instant::now()));
        answers.push(vehicle.ask(id, u64::from(sequence)).1);
    }
    answers
}

/// The longest time without an answer between `start` and `end`: between two answers, or
/// from the start to the first, or from the last to the end.
fn longest_gap(start: Instant, end: Instant, answers: &[Option<Instant>]) -> Duration {
    let mut last = start;
    let mut longest = Duration::ZERO;
    for at in answers.iter().flatten() {
        longest = longest.max(at.saturating_duration_since(last));
        last = *at;
    }
    longest.max(end.saturating_duration_since(last))
}

/// Resumes a stopped process when dropped, also when the test panics.
struct Resume(u32);

impl Drop for Resume {
    fn drop(&mut self) {
        signal(self.0, "CONT");
    }
}

#[test]
fn plain_key_vehicles_are_answered_while_an_instance_hangs() {
    let network = RoutedPlanners::start("plain-hang");
    drop(network.vehicle(DEADLINE));
    // Two vehicles of each instance (by rendezvous hashing).
    let mut ids = Vec::new();
    for instance in INSTANCES {
        ids.extend((1..).filter(|v| rendezvous_order(*v, INSTANCES)[0] == instance).take(2));
    }
    // 1 s of service, each instance stopped 3 s in turn with 3 s between.
    let phases = [(1, 4), (7, 10)];
    let end = Duration::from_secs(13);
    let pids: Vec<u32> = network.planners.iter().map(|p| p.id()).collect();
    let start = Instant::now() + Duration::from_millis(500);
    let results: Vec<(u64, Vec<Option<Instant>>)> = std::thread::scope(|scope| {
        let vehicles: Vec<_> = ids
            .iter()
            .enumerate()
            .map(|(i, &id)| {
                let network = &network;
                scope.spawn(move || {
                    let mode = if i % 2 == 0 {
                        ConsolidationMode::Auto
                    } else {
                        ConsolidationMode::None
                    };
                    let vehicle = PlainVehicle::connect(network, mode);
                    (id, drive(&vehicle, id, start, end))
                })
            })
            .collect();
        for ((stop_s, resume_s), pid) in phases.iter().zip(&pids) {
            std::thread::sleep((start + Duration::from_secs(*stop_s)).saturating_duration_since(Instant::now()));
            signal(*pid, "STOP");
            let resume = Resume(*pid);
            std::thread::sleep((start + Duration::from_secs(*resume_s)).saturating_duration_since(Instant::now()));
            drop(resume);
        }
        vehicles
            .into_iter()
            .map(|v| v.join().expect("vehicle thread"))
            .collect()
    });
    let mut worst = Duration::ZERO;
    for (id, answers) in &results {
        let gap = longest_gap(start, start + end, answers);
        let lost = answers.iter().filter(|a| a.is_none()).count();
        eprintln!(
            "vehicle {id} (instance {}): {} requests, {lost} unanswered, longest gap {gap:?}",
            rendezvous_order(*id, INSTANCES)[0],
            answers.len()
        );
        worst = worst.max(gap);
    }
    eprintln!("plain key, each instance stopped 3 s in turn: longest gap between answers {worst:?}");
    // The gap is the measurement (docs/deploy.md); asserted is only that every vehicle is
    // answered while an instance still hangs, from 1 s to 2.5 s into each 3 s stop: without
    // the forward and the short lease, plain-key vehicles got nothing for 2.96 s.
    for (id, answers) in &results {
        for (stop_s, resume_s) in phases {
            let from = start + Duration::from_secs(stop_s + 1);
            let to = start + Duration::from_millis(resume_s * 1000 - 500);
            let served = answers.iter().flatten().filter(|at| (from..to).contains(*at)).count();
            assert!(
                served > 0,
                "vehicle {id}: no answer 1-2.5 s into the stop at {stop_s} s\n{}",
                network.logs()
            );
        }
    }
}
