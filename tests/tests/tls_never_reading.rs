//! The never-reading client over TLS, against the shipped TLS + access-control deployment:
//! `hmdp-router` with `deploy/zenoh/router-tls.json5`, the planner on the router's host with
//! its shipped file, a normal vehicle with `client-tls.json5`, certificates from
//! `deploy/tls/make-certs`. The attacker holds a valid vehicle certificate and opens three
//! TLS sessions that send queries (congestion control *block*, none of the project's QoS
//! rules, small socket buffers) and never read the replies.
//!
//! zenoh-link-tls 1.10 lets a link's reading and writing tasks use one `rustls` stream at the
//! same time (upstream eclipse-zenoh/zenoh#2557): a process whose TLS link is read and written
//! hard at once corrupts its memory and aborts. With the planner on a TLS link that process
//! was the planner (the attacker's queries in, the replies out). The shipped deployment keeps
//! the planner off TLS (it reaches the router over loopback TCP, docs/deploy.md). The
//! attacker's queries and the normal vehicle's share the router's one link to the planner:
//! unchecked, they queued there behind thousands of the attacker's, and most of the vehicle's
//! answers came 0.1 to 1.5 s late. The router's TLS listener therefore reads each vehicle
//! link at a bounded rate (`ingress_bytes_per_s` in `router-tls.json5`, the workspace's
//! patched zenoh-link-tls): the attacker's excess waits in its own connections.
//!
//! Asserted: the router and the planner live through the attack, the attack happened, the
//! normal vehicle gets every answer within its own wait for it (a second) and at most 1 % of
//! them are watchdog fallbacks (counts, never timings). CI runs 5 s of attack; the 20 s
//! measurement of docs/deploy.md is an ignored test with the same assertions.
//!
//! To see the test fail on other configurations: `HMDP_TLS_WITHOUT_INGRESS_LIMIT=1` removes
//! the ingress limit from the router's TLS listener (the vehicle's answers come late again),
//! `HMDP_TLS_PLANNER_CONFIG=planner-tls.json5` runs the planner with another file of
//! `deploy/zenoh/` (there: on a TLS link to the router), and `HMDP_TLS_WITHOUT_QOS=1` removes
//! the `plan-replies-never-block` rule from every file (replies then block on the attacker's
//! full link, as when issue 12 was filed).
//!
//! The attacker is this test executable run again as a child process in the role
//! [`never_reading_tls_attacker`].

use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use system_tests::{normal_vehicle, scratch_dir, send_without_reading, Process, TlsFiles};
use transport::zenoh::{ZenohChannel, ZenohTarget};
use zenoh::Wait;

/// Environment variable that turns this executable into the attacker: its Zenoh file.
const ATTACK_CONFIG: &str = "HMDP_TLS_ATTACK_CONFIG";
/// Environment variable naming the planner's file in `deploy/zenoh/` (default below).
const PLANNER_CONFIG: &str = "HMDP_TLS_PLANNER_CONFIG";
/// The planner's file of the shipped TLS deployment (the planner on the router's host).
const SHIPPED_PLANNER_CONFIG: &str = "planner-local.json5";
/// Environment variable: `1` removes the QoS rule from the router's and the planner's files.
const WITHOUT_QOS: &str = "HMDP_TLS_WITHOUT_QOS";
/// Environment variable: `1` removes the ingress limit from the router's TLS listener.
const WITHOUT_INGRESS_LIMIT: &str = "HMDP_TLS_WITHOUT_INGRESS_LIMIT";
/// Attacker sessions, as in the probe that killed the planner (issue 12).
const ATTACK_SESSIONS: u64 = 3;
/// The normal vehicle's requests in the longer measurement, at 20 Hz (20 s of attack).
const REQUESTS: u64 = 400;
/// In CI: 5 s of attack (each lost request costs the vehicle its 1 s wait, and the attack
/// takes both cores of a small machine while it lasts).
const CI_REQUESTS: u64 = 100;

/// Child role: `ATTACK_SESSIONS` TLS sessions with the vehicle's certificate that send
/// queries (block, JSON: the larger answers fill the buffers sooner) and stall their receiving
/// at the first reply, until killed; prints how many queries it sent every second. Does
/// nothing unless started by the test below.
#[test]
#[ignore = "a role of the TLS never-reading test, started by it as a child process"]
fn never_reading_tls_attacker() {
    let Ok(file) = std::env::var(ATTACK_CONFIG) else {
        return;
    };
    let sent = Arc::new(AtomicU64::new(0));
    for k in 0..ATTACK_SESSIONS {
        let (file, sent) = (file.clone(), Arc::clone(&sent));
        std::thread::spawn(move || {
            let mut config = zenoh::Config::from_file(&file).expect("attacker config");
            // An attacker keeps none of the project's QoS rules, and reads slowly.
            config.insert_json5("qos/network", "[]").unwrap();
            config.insert_json5("transport/link/tls/so_rcvbuf", "4096").unwrap();
            let session = zenoh::open(config).wait().expect("attacker session");
            send_without_reading(&session, 900 + k, &sent)
        });
    }
    loop {
        std::thread::sleep(Duration::from_secs(1));
        eprintln!("attacker sent {}", sent.load(Ordering::Relaxed));
    }
}

/// `file` without its QoS rule if `WITHOUT_QOS` asks for it (the rule is the last part of
/// every shipped file).
fn maybe_without_qos(file: std::path::PathBuf) -> std::path::PathBuf {
    if std::env::var(WITHOUT_QOS).as_deref() != Ok("1") {
        return file;
    }
    let text = std::fs::read_to_string(&file).unwrap();
    let cut = text.find("  qos: {").expect("a qos section");
    let stripped = format!("{}}}\n", &text[..cut]);
    assert!(!stripped.contains("plan-replies-never-block"), "{}", file.display());
    std::fs::write(&file, stripped).unwrap();
    zenoh::Config::from_file(&file).expect("the file without its QoS rule");
    file
}

/// The router's `file` without its TLS listener's ingress limit if `WITHOUT_INGRESS_LIMIT`
/// asks for it.
fn maybe_without_ingress_limit(file: std::path::PathBuf) -> std::path::PathBuf {
    if std::env::var(WITHOUT_INGRESS_LIMIT).as_deref() != Ok("1") {
        return file;
    }
    let text = std::fs::read_to_string(&file).unwrap();
    let limit = format!(
        ";ingress_bytes_per_s={};ingress_burst_bytes={}",
        transport::zenoh::TLS_INGRESS_BYTES_PER_S,
        transport::zenoh::TLS_INGRESS_BURST_BYTES
    );
    assert!(text.contains(&limit), "{} no longer sets {limit}", file.display());
    std::fs::write(&file, text.replace(&limit, "")).unwrap();
    file
}

/// The last count the attacker printed.
fn attacker_sent(log: &std::path::Path) -> u64 {
    std::fs::read_to_string(log)
        .unwrap_or_default()
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("attacker sent ")?.trim().parse().ok())
        .unwrap_or(0)
}

/// What CI holds: the processes live through 5 s of attack, the attack happened, and the
/// normal vehicle got every answer within its wait, decided by the solver, not the watchdog.
#[test]
fn never_reading_tls_peers_kill_nothing() {
    let figures = run_attack(CI_REQUESTS);
    assert_costs_nothing(&figures, CI_REQUESTS);
}

/// The same over 20 s of attack, the measurement of docs/deploy.md ("TLS links"). Run it
/// with `cargo nextest run -p system_tests --run-ignored only -E
/// 'test(cost_other_vehicles_nothing)'`.
#[test]
#[ignore = "20 s of attack on both cores; CI runs the 5 s one (never_reading_tls_peers_kill_nothing)"]
fn never_reading_tls_peers_cost_other_vehicles_nothing() {
    let figures = run_attack(REQUESTS);
    assert_costs_nothing(&figures, REQUESTS);
}

/// Every one of the normal vehicle's requests answered within its wait, at most 1 % of them
/// by the watchdog.
fn assert_costs_nothing(figures: &system_tests::VictimFigures, requests: u64) {
    assert_eq!(figures.answered, figures.sent, "answers lost or late: {figures:?}");
    assert!(figures.watchdog <= requests / 100, "{figures:?}");
}

/// Starts the shipped TLS deployment and the attacker, drives the normal vehicle through the
/// attack, asserts that every process lived through it and the attack happened, and returns
/// the normal vehicle's figures.
fn run_attack(requests: u64) -> system_tests::VictimFigures {
    let tls = TlsFiles::new("tls-never-reading", &[]);
    let planner_file = std::env::var(PLANNER_CONFIG).unwrap_or_else(|_| SHIPPED_PLANNER_CONFIG.into());
    let router_config = maybe_without_ingress_limit(maybe_without_qos(tls.render("router-tls.json5")));
    let mut router = Process::start(
        "hmdp-router",
        &["--config", router_config.to_str().unwrap()],
        "tls-never-reading-router",
    );
    let planner_config = maybe_without_qos(tls.render(&planner_file));
    let mut planner = Process::start(
        "planner",
        &[
            "serve",
            "--zenoh-config",
            planner_config.to_str().unwrap(),
            "--workers",
            "2",
        ],
        "tls-never-reading-planner",
    );
    let target = ZenohTarget {
        config_file: Some(tls.render("client-tls.json5")),
        ..ZenohTarget::default()
    };
    let channel = ZenohChannel::connect(&target, Duration::from_secs(60), Duration::from_secs(5)).unwrap_or_else(|e| {
        panic!(
            "the TLS deployment never answered: {e}\nrouter:\n{}\nplanner:\n{}",
            router.log(),
            planner.log()
        )
    });
    let attacker_log = scratch_dir("tls-never-reading").join("attacker.log");
    let mut attacker = supervise::Supervised::spawn(
        Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "never_reading_tls_attacker", "--ignored", "--nocapture"])
            .env(ATTACK_CONFIG, target.config_file.as_ref().unwrap())
            .env("RUST_LOG", "error")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&attacker_log).unwrap()),
        true,
    )
    .expect("attacker starts");
    // Let the attacker's replies pile up in its socket buffers.
    std::thread::sleep(Duration::from_secs(3));
    let figures = normal_vehicle(&channel, requests, || router.is_running() && planner.is_running());
    let attacker_running = attacker.is_running();
    attacker.kill();
    let sent = attacker_sent(&attacker_log);
    eprintln!("planner file {planner_file}: attacker sent {sent} queries; normal vehicle: {figures:?}");
    // A process that exited shows how (an abort: SIGABRT), a running one `None`.
    let exited = |p: &mut Process| (!p.is_running()).then(|| p.terminate(Duration::ZERO));
    let (router_exit, planner_exit) = (exited(&mut router), exited(&mut planner));
    assert!(
        router_exit.is_none() && planner_exit.is_none(),
        "died under the attack: router {router_exit:?}, planner {planner_exit:?} ({figures:?})\nrouter:\n{}\nplanner:\n{}",
        router.log(),
        planner.log()
    );
    assert!(
        attacker_running,
        "the attacker stopped by itself\n{}",
        std::fs::read_to_string(&attacker_log).unwrap_or_default()
    );
    assert!(sent >= 100, "the attack did not happen: {sent} queries sent");
    assert_eq!(figures.sent, requests);
    figures
}
