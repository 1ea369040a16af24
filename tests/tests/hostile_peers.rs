//! `planner serve` over Zenoh against hostile peers on the same network: each test runs the
//! attack for real, beside a normal vehicle, and asserts what the normal vehicle got (counts,
//! never timings: the machine is shared).
//!
//! * SIGPIPE is ignored by `serve`;
//! * oversized queries are dropped while being reassembled, and the planner's memory stays
//!   bounded; their sender's query ends at its own timeout, with nothing back (nothing can
//!   come: the planner never sees them), and one just below the limit gets a typed rejection;
//! * a peer that sends queries and never reads the replies costs the others nothing;
//! * a vehicle that floods does not starve another.
//!
//! The never-reading attacker is this test executable run again as a child process in the
//! role [`never_reading_attacker`] (its own Zenoh runtime, stalled on purpose).

use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use protocol::{encode_bincode, ZENOH_PLAN_KEY};
use system_tests::{normal_vehicle, send_without_reading, worked_example_request, ZenohPlanner as Planner};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

/// Environment variable that turns this executable into the never-reading attacker.
const ATTACK_ENDPOINT: &str = "HMDP_NEVER_READING_ENDPOINT";

/// A Zenoh client session as an attacker would configure it: none of the project's
/// hardening, queries with congestion control *block*. `extra` is merged into the top level.
fn attacker_session(endpoint: &str, extra: serde_json::Value) -> zenoh::Session {
    let mut json = serde_json::json!({
        "mode": "client",
        "connect": { "endpoints": [endpoint] },
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
    });
    json.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    let config = zenoh::Config::from_json5(&json.to_string()).expect("attacker config");
    zenoh::open(config).wait().expect("attacker session")
}

/// A field of `/proc/PID/status`, e.g. `VmHWM` (kB) or `SigIgn` (hex mask), as text.
fn proc_status(pid: u32, field: &str) -> String {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("/proc status");
    status
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{field}:")))
        .unwrap_or_else(|| panic!("no {field} in /proc/{pid}/status"))
        .trim()
        .to_string()
}

#[test]
fn serve_ignores_sigpipe() {
    let planner = Planner::start("sigpipe", &[]);
    drop(planner.vehicle(None));
    let mask = u64::from_str_radix(&proc_status(planner.process.id(), "SigIgn"), 16).unwrap();
    assert_ne!(mask & (1 << (SIGPIPE - 1)), 0, "SIGPIPE not ignored: SigIgn {mask:x}");
}

/// SIGPIPE's number on Linux.
const SIGPIPE: u32 = 13;

#[test]
fn oversized_queries_are_dropped_unbuffered_and_memory_stays_bounded() {
    const BIG: usize = 100 * 1024 * 1024;
    let planner = Planner::start("oversized", &[]);
    let channel = planner.vehicle(None);
    let before_kb: u64 = proc_status(planner.process.id(), "VmHWM")
        .trim_end_matches(" kB")
        .parse()
        .unwrap();
    // Four 100 MB queries at once, from four sessions.
    let answers: Vec<usize> = std::thread::scope(|scope| {
        let senders: Vec<_> = (0..4u8)
            .map(|i| {
                let endpoint = planner.endpoint.clone();
                scope.spawn(move || {
                    let session = attacker_session(&endpoint, serde_json::json!({}));
                    let replies = session
                        .get(ZENOH_PLAN_KEY)
                        .payload(vec![i; BIG])
                        .congestion_control(CongestionControl::Block)
                        .timeout(Duration::from_secs(20))
                        .wait()
                        .expect("query sent");
                    // Nothing can come back: the message never reaches the planner, and
                    // Zenoh sends no word of the drop. The query ends at the sender's own
                    // timeout, with Zenoh's "Timeout" error: that bounds its wait.
                    let (mut answers, mut timed_out) = (0, false);
                    while let Ok(reply) = replies.recv() {
                        match reply.result() {
                            Ok(_) => answers += 1,
                            Err(e) => timed_out |= e.payload().try_to_string().is_ok_and(|s| s == "Timeout"),
                        }
                    }
                    let _ = session.close().wait();
                    assert!(timed_out, "the query did not end at its timeout");
                    answers
                })
            })
            .collect();
        senders.into_iter().map(|s| s.join().unwrap()).collect()
    });
    let after_kb: u64 = proc_status(planner.process.id(), "VmHWM")
        .trim_end_matches(" kB")
        .parse()
        .unwrap();
    eprintln!("planner peak RSS: {before_kb} kB before, {after_kb} kB after four 100 MB queries");
    assert_eq!(answers, vec![0; 4], "an oversized query reached the planner");
    // Below the limit the planner has the query whole, and answers it: a typed rejection.
    let session = attacker_session(&planner.endpoint, serde_json::json!({}));
    let replies = session
        .get(ZENOH_PLAN_KEY)
        .payload(vec![0xab; 60_000])
        .timeout(Duration::from_secs(20))
        .wait()
        .expect("query sent");
    let reply = replies.recv().expect("an answer");
    let response: protocol::PlanResponse =
        protocol::decode_bincode(&reply.result().expect("an answer").payload().to_bytes()).unwrap();
    // Junk bytes: refused for their version (the first two bytes), typed either way.
    assert!(
        matches!(response.outcome.as_rejected().map(|r| r.reason()), Some(Ok(_))),
        "{response:?}"
    );
    // The service goes on.
    let figures = normal_vehicle(&channel, 10, || true);
    assert_eq!(figures.answered, 10, "{figures:?}\n{}", planner.log());
    assert!(
        after_kb < 100 * 1024,
        "planner peak RSS {after_kb} kB\n{}",
        planner.log()
    );
}

/// Child role: three sessions that send queries (congestion control *block*, kept small
/// socket buffers) and stall their receiving at the first reply, until killed. Does nothing
/// unless started by [`a_peer_that_never_reads_costs_other_vehicles_nothing`].
#[test]
#[ignore = "a role of the never-reading test, started by it as a child process"]
fn never_reading_attacker() {
    let Ok(endpoint) = std::env::var(ATTACK_ENDPOINT) else {
        return;
    };
    let threads: Vec<_> = (0..3u64)
        .map(|k| {
            let endpoint = endpoint.clone();
            std::thread::spawn(move || {
                let session = attacker_session(
                    &endpoint,
                    serde_json::json!({ "transport": { "link": { "tcp": { "so_rcvbuf": 4096 } } } }),
                );
                send_without_reading(&session, 900 + k, &AtomicU64::new(0))
            })
        })
        .collect();
    for t in threads {
        let _ = t.join();
    }
}

#[test]
fn a_peer_that_never_reads_costs_other_vehicles_nothing() {
    let planner = Planner::start("never-reading", &[]);
    let channel = planner.vehicle(None);
    let mut attacker = supervise::Supervised::spawn(
        Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "never_reading_attacker", "--ignored", "--nocapture"])
            .env(ATTACK_ENDPOINT, &planner.endpoint)
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
        true,
    )
    .expect("attacker starts");
    // Let the attacker's replies pile up in its socket buffers.
    std::thread::sleep(Duration::from_secs(3));
    let figures = normal_vehicle(&channel, 200, || true);
    assert!(attacker.is_running(), "the attacker stopped by itself");
    attacker.kill();
    eprintln!("normal vehicle beside a never-reading peer: {figures:?}");
    assert_eq!(figures.answered, figures.sent, "{figures:?}\n{}", planner.log());
    assert!(figures.watchdog <= 1, "{figures:?}");
}

#[test]
fn a_flooding_vehicle_does_not_starve_another() {
    let planner = Planner::start("flood", &[]);
    let channel = planner.vehicle(None);
    let stop = Arc::new(AtomicBool::new(false));
    let flood_replies = Arc::new(AtomicU64::new(0));
    // Vehicle 666, from two sessions, about 2,000 real requests per second without waiting
    // for the answers.
    let flooders: Vec<_> = (0..2)
        .map(|_| {
            let (endpoint, stop, replies) = (planner.endpoint.clone(), Arc::clone(&stop), Arc::clone(&flood_replies));
            std::thread::spawn(move || {
                let session = attacker_session(&endpoint, serde_json::json!({}));
                let mut sequence = 0;
                while !stop.load(Ordering::Relaxed) {
                    sequence += 1;
                    let replies = Arc::clone(&replies);
                    let _ = session
                        .get(ZENOH_PLAN_KEY)
                        .payload(encode_bincode(&worked_example_request(666, sequence)))
                        .timeout(Duration::from_secs(2))
                        .callback(move |_| {
                            replies.fetch_add(1, Ordering::Relaxed);
                        })
                        .wait();
                    std::thread::sleep(Duration::from_millis(1));
                }
                let _ = session.close().wait();
            })
        })
        .collect();
    std::thread::sleep(Duration::from_secs(1));
    let figures = normal_vehicle(&channel, 100, || true);
    stop.store(true, Ordering::Relaxed);
    for f in flooders {
        f.join().unwrap();
    }
    let flooded = flood_replies.load(Ordering::Relaxed);
    eprintln!("normal vehicle beside a flooding one ({flooded} flood answers): {figures:?}");
    assert!(flooded > 1000, "the flood did not happen: {flooded} answers");
    assert_eq!(figures.answered, figures.sent, "{figures:?}\n{}", planner.log());
    assert!(figures.watchdog <= 1, "{figures:?}");
}
