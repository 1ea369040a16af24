//! Secure by default across machines: the shipped deployment signs answers, and a vehicle
//! that reaches a planner beyond this host without the planner's public key refuses to run
//! (unless told `--insecure`, which it logs), so that a forged planner on the network cannot
//! command it.
//!
//! * `sim_client` and the Python client, pointed without a key at an address beyond this
//!   host (an unreachable documentation address, and the shipped `client.json5`), refuse to
//!   start and say why, before they send anything.
//! * The shipped plain-router set-up (`deploy/zenoh/router.json5`, `planner.json5`,
//!   `client.json5`, the planner started with the systemd unit's own flags) on this
//!   machine's non-loopback address, with a forger answering every plan query first:
//!   vehicles without the key refuse to run; with it, `sim_client load` and the Python
//!   client take only the planner's answers (the planner's own count agrees) and refuse the
//!   forgeries; `--insecure` runs and says so.
//!
//! The second test needs a non-loopback IPv4 address on this machine (no network traffic
//! leaves it); `HMDP_SKIP_NON_LOOPBACK=1` skips it where there is none.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::Ordering;
use std::time::Duration;

use protocol::ResponseVerifier;

use system_tests::forger::{Forger, FORGED_ACCEL};
use system_tests::{binary, free_port, keygen, python_ready, scratch_dir, Iceoryx2Prefix, Process};
use transport::zenoh::{ZenohChannel, ZenohTarget};

/// A documentation address (RFC 5737): beyond this host, and nothing answers there.
const UNREACHABLE: &str = "tcp/198.51.100.7:7447";
/// What the refusals say (the Rust error and the Python one).
const REFUSAL: &str = "cannot be verified";

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `sim_client args...`: (exit success, stdout, stderr).
fn sim_client(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(binary("sim_client"))
        .args(args)
        .output()
        .expect("sim_client runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `python3 clients/python/hmdp_client.py args...`: (exit code, stdout, stderr).
fn python_client(args: &[&str]) -> (i32, String, String) {
    let out = Command::new("python3")
        .arg(repo().join("clients/python/hmdp_client.py"))
        .args(args)
        .output()
        .expect("python3 runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `deploy/zenoh/NAME` with `from` replaced by `to`, written into `dir`.
fn render(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("deploy/zenoh").join(name)).unwrap();
    assert!(text.contains(from), "{name} no longer holds {from}");
    let path = dir.join(name);
    std::fs::write(&path, text.replace(from, to)).unwrap();
    path
}

#[test]
fn vehicles_refuse_an_unverified_planner_beyond_this_host() {
    let dir = scratch_dir("secure-refusal");
    let client_file = repo().join("deploy/zenoh/client.json5");
    for target in [
        vec!["--zenoh-connect", UNREACHABLE],
        vec!["--zenoh-config", client_file.to_str().unwrap()],
    ] {
        let out = dir.join("out");
        let mut args = vec!["case1", "--transport", "zenoh", "--out", out.to_str().unwrap()];
        args.extend(&target);
        let (ok, stdout, stderr) = sim_client(&args);
        assert!(!ok && stderr.contains(REFUSAL), "{target:?}: {stdout}\n{stderr}");
        assert!(!stdout.contains("decisions"), "{target:?}: {stdout}");
    }
    if python_ready("zenoh", "run scripts/install-build-deps") {
        let (code, stdout, stderr) = python_client(&["--connect", UNREACHABLE]);
        assert!(code == 1 && stderr.contains(REFUSAL), "exit {code}\n{stdout}\n{stderr}");
    }
}

/// A non-loopback IPv4 address of this machine, from `ip -o -4 addr show scope global`.
fn address_beyond_loopback() -> Option<String> {
    let out = Command::new("ip")
        .args(["-o", "-4", "addr", "show", "scope", "global"])
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let field = text.split_whitespace().skip_while(|w| *w != "inet").nth(1)?;
    Some(field.split('/').next()?.to_string())
}

/// The arguments of `planner serve` in the shipped systemd unit, with this test's files.
fn unit_serve_args(key: &Path, zenoh_file: &Path, prefix: &str) -> Vec<String> {
    let unit = std::fs::read_to_string(repo().join("deploy/systemd/hmdp-planner.service")).unwrap();
    let line = unit
        .lines()
        .find_map(|l| l.strip_prefix("ExecStart="))
        .expect("ExecStart in the unit");
    let mut words: Vec<String> = line.split_whitespace().skip(1).map(str::to_owned).collect();
    assert!(
        words.iter().any(|w| w == "--signing-key"),
        "the shipped unit does not sign: {line}"
    );
    let planner_toml = repo().join("deploy/planner.toml");
    for word in &mut words {
        *word = match word.as_str() {
            "/etc/hmdp/planner.key" => key.display().to_string(),
            "/etc/hmdp/zenoh/planner.json5" => zenoh_file.display().to_string(),
            "/etc/hmdp/planner.toml" => planner_toml.display().to_string(),
            other => {
                assert!(
                    !other.starts_with("/etc/"),
                    "the unit names a file this test does not provide: {other}"
                );
                other.to_owned()
            }
        };
    }
    words.extend([
        "--iceoryx2-prefix".into(),
        prefix.into(),
        "--workers".into(),
        "2".into(),
    ]);
    words
}

#[test]
fn the_shipped_router_setup_signs_and_its_vehicles_take_no_forgery() {
    let Some(address) = address_beyond_loopback() else {
        if std::env::var("HMDP_SKIP_NON_LOOPBACK").as_deref() == Ok("1") {
            eprintln!("skipped: no non-loopback address and HMDP_SKIP_NON_LOOPBACK=1");
            return;
        }
        panic!("no non-loopback IPv4 address on this machine; set HMDP_SKIP_NON_LOOPBACK=1 to skip this test");
    };
    let dir = scratch_dir("secure-shipped");
    let (key, public) = keygen(&dir, "planner.key");
    // The router listens where vehicles reach it, and on loopback for the planner beside it.
    let (port, local_port) = (free_port(), free_port());
    let endpoint = format!("tcp/{address}:{port}");
    let router_file = repo().join("deploy/zenoh/router.json5");
    let local = format!("tcp/127.0.0.1:{local_port}");
    let router = Process::start(
        "hmdp-router",
        &[
            "--config",
            router_file.to_str().unwrap(),
            "--listen",
            &endpoint,
            "--listen",
            &local,
        ],
        "secure-router",
    );
    let planner_file = render(&dir, "planner.json5", "tcp/127.0.0.1:7447", &local);
    let prefix = Iceoryx2Prefix::new("secure");
    let args = unit_serve_args(&key, &planner_file, prefix.as_str());
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut planner = Process::start("planner", &args, "secure-planner");
    let client_file = render(&dir, "client.json5", "tcp/hmdp-router:7447", &endpoint);
    let logs = || format!("router:\n{}\nplanner:\n{}", router.log(), planner.log());

    // With the key: connects once the planner serves (its probe answer verifies).
    let report = dir.join("load.json");
    let load = |extra: &[&str]| {
        let mut args = vec![
            "load",
            "--transport",
            "zenoh",
            "--zenoh-config",
            client_file.to_str().unwrap(),
            "--clients",
            "1",
            "--rate",
            "10",
            "--duration",
            "8s",
            "--warmup",
            "0s",
            "--out",
            dir.to_str().unwrap(),
            "--json",
            report.to_str().unwrap(),
        ];
        args.extend(extra);
        sim_client(&args)
    };
    // Serving (the router up, the planner's probe answer verified) before the forger comes.
    let ready = ZenohTarget {
        config_file: Some(client_file.clone()),
        verifier: Some(ResponseVerifier::from_file(&public).unwrap()),
        ..ZenohTarget::default()
    };
    drop(
        ZenohChannel::connect(&ready, Duration::from_secs(60), Duration::from_secs(5))
            .unwrap_or_else(|e| panic!("the shipped set-up never answered: {e}\n{}", logs())),
    );
    let forger = Forger::start(&endpoint, 0);
    let (ok, stdout, stderr) = load(&["--planner-key", public.to_str().unwrap()]);
    assert!(ok, "{stdout}\n{stderr}\n{}", logs());
    let counts =
        serde_json::from_slice::<serde_json::Value>(&std::fs::read(&report).unwrap()).unwrap()["counts"].clone();
    let forgeries = forger.sent.load(Ordering::SeqCst);

    // Without it: refused before anything is sent.
    let (ok, stdout, stderr) = load(&[]);
    assert!(!ok && stderr.contains(REFUSAL), "without the key: {stdout}\n{stderr}");

    let python = python_ready("zenoh, cryptography", "run scripts/install-build-deps").then(|| {
        let (code, stdout, stderr) = python_client(&["--connect", &endpoint]);
        assert!(code == 1 && stderr.contains(REFUSAL), "exit {code}\n{stdout}\n{stderr}");
        let steps = ["--steps", "10", "--timeout", "3"];
        let (code, stdout, stderr) = python_client(
            &[
                &["--connect", &endpoint, "--planner-key", public.to_str().unwrap()],
                &steps[..],
            ]
            .concat(),
        );
        assert_eq!(code, 0, "{stdout}\n{stderr}\n{}", logs());
        let forged_lines = |stdout: &str| {
            stdout
                .lines()
                .filter(|l| l.contains(&format!("\"accel_mps2\": {FORGED_ACCEL}")))
                .count()
        };
        assert_eq!(stdout.lines().count(), 10, "{stdout}");
        assert_eq!(forged_lines(&stdout), 0, "took a forgery: {stdout}");
        assert!(stderr.contains("refused"), "{stderr}");
        // --insecure runs, and says so; the forger is then believed whenever it answers
        // first (one step per run: a forged plan would derail the next snapshot).
        (0..10)
            .map(|_| {
                let (code, stdout, stderr) = python_client(&["--connect", &endpoint, "--insecure", "--timeout", "3"]);
                assert!(
                    code == 0 && stderr.contains("INSECURE"),
                    "exit {code}\n{stdout}\n{stderr}"
                );
                forged_lines(&stdout)
            })
            .sum::<usize>()
    });

    let before = logs();
    assert!(
        planner.terminate(Duration::from_secs(10)).is_some_and(|s| s.success()),
        "{before}"
    );
    let stats = planner.final_statistics();
    eprintln!(
        "shipped router set-up on {endpoint}, forger answering first ({forgeries} forgeries sent to the load run): \
         sim_client load with the key: {counts}; planner decided {}; Python with the key: 0 of 10 forged; \
         Python --insecure took {python:?} of 10 forgeries",
        stats["answered"]
    );
    assert!(forgeries > 0, "the forger never answered\n{before}");
    let (sent, in_time, late, refused) = (
        counts["sent"].as_u64().unwrap(),
        counts["in_time"].as_u64().unwrap(),
        counts["late"].as_u64().unwrap(),
        counts["refused"].as_u64().unwrap(),
    );
    // Every request got the planner's answer (late ones too: a loaded machine is slow, and
    // timing is the load tool's measurement, not this test's).
    assert!(sent >= 40 && in_time + late == sent, "{counts}");
    assert!(refused > 0, "no forgery reached the vehicle: {counts}");
    // Every answer the vehicle took was the planner's: the planner decided at least as many.
    assert!(
        stats["answered"].as_u64().unwrap() >= in_time + late,
        "{stats} {counts}"
    );
}
