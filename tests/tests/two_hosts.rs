//! The two-host deployment as processes: `scripts/two-host-demo --check-rejections` puts the
//! router and the planner in one network namespace and the vehicle in another, over mutual
//! TLS with access control, with the binaries of this test's own profile.
//!
//! It checks that the vehicle got its 100 decisions without a collision, that clients the
//! router must refuse (a certificate from another CA, no certificate, a valid certificate with
//! an unknown name) got none — on the client side and by the planner's own count — and that
//! the planner signs: the vehicle verifies its answers, and refuses to run without its key.
//!
//! Needs root and `ip netns` (iproute2) plus openssl; fails otherwise, unless
//! `HMDP_SKIP_NETNS=1` is set.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use system_tests::binary;

/// Above the script's own bounds (startup, a 40 s scene, 10 s rejection checks): only a
/// hung run reaches it.
const OVERALL: Duration = Duration::from_secs(180);

fn effective_uid() -> Option<u32> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("Uid:"))?;
    line.split_whitespace().nth(2)?.parse().ok()
}

/// Why network namespaces cannot be used here, if they cannot.
fn netns_unavailable() -> Option<String> {
    if effective_uid() != Some(0) {
        return Some("not running as root".into());
    }
    match Command::new("ip").args(["netns", "list"]).output() {
        Ok(out) if out.status.success() => None,
        Ok(out) => Some(format!(
            "`ip netns list` failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )),
        Err(e) => Some(format!("cannot run `ip` (iproute2): {e}")),
    }
}

fn scratch_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hmdp-two-hosts-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn vehicle_and_planner_on_two_hosts_over_mutual_tls() {
    if std::env::var("HMDP_SKIP_NETNS").as_deref() == Ok("1") {
        eprintln!("two_hosts: skipped (HMDP_SKIP_NETNS=1)");
        return;
    }
    if let Some(why) = netns_unavailable() {
        panic!(
            "two_hosts needs root and network namespaces (`ip netns`, iproute2) and openssl: {why}. \
             Run the tests as root, or set HMDP_SKIP_NETNS=1 to skip this test."
        );
    }
    let planner = binary("planner");
    binary("sim_client");
    binary("hmdp-router");
    let bin_dir = planner.parent().expect("profile directory");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/two-host-demo");
    let dir = scratch_dir();
    let (stdout_path, stderr_path) = (dir.join("stdout"), dir.join("stderr"));

    let started = Instant::now();
    let mut child = Command::new("bash")
        .arg(&script)
        .arg("--bin-dir")
        .arg(bin_dir)
        .arg("--check-rejections")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&stdout_path).unwrap())
        .stderr(std::fs::File::create(&stderr_path).unwrap())
        .spawn()
        .expect("scripts/two-host-demo starts");
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if started.elapsed() > OVERALL {
            // SIGTERM lets the script's trap remove its namespaces and processes.
            let _ = Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
            let until = Instant::now() + Duration::from_secs(15);
            while Instant::now() < until && child.try_wait().unwrap().is_none() {
                std::thread::sleep(Duration::from_millis(100));
            }
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let wall = started.elapsed();
    let stdout = std::fs::read_to_string(&stdout_path).unwrap_or_default();
    let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    let report = format!("---- stdout ----\n{stdout}\n---- stderr ----\n{stderr}");
    eprintln!("two_hosts: scripts/two-host-demo took {:.1} s", wall.as_secs_f64());

    let status = status.unwrap_or_else(|| panic!("two-host-demo still running after {OVERALL:?}\n{report}"));
    assert!(status.success(), "two-host-demo failed: {status}\n{report}");

    // The vehicle, through the router, from the other namespace.
    let summary = stdout
        .lines()
        .find(|l| l.starts_with("case1: "))
        .unwrap_or_else(|| panic!("no case1 summary\n{report}"));
    assert!(summary.starts_with("case1: 100 decisions"), "{summary}\n{report}");
    assert!(summary.contains(", collisions 0 "), "{summary}\n{report}");
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with("case1: ")).count(),
        1,
        "only the authorised vehicle may get decisions\n{report}"
    );

    // The clients the router must refuse.
    for name in ["foreign-ca", "no-cert", "unknown-cn"] {
        let line = format!("two-host-demo: rejection check {name}: no decisions");
        assert!(stdout.contains(&line), "missing `{line}`\n{report}");
    }
    // Without the planner's public key the vehicle refuses to run (answers signed by default).
    assert!(
        stdout.contains("two-host-demo: rejection check no-planner-key: the vehicle refused to run"),
        "{report}"
    );
    // The planner's own count: nothing decided for anyone but the vehicle.
    assert!(
        stdout.contains("two-host-demo: planner: 100 decisions, all for the authorised vehicle"),
        "{report}"
    );
}
