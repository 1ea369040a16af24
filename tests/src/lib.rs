//! Helpers for tests that run the workspace's binaries as separate processes.

use std::path::PathBuf;
use std::time::Duration;

mod attacker;
pub mod forger;
pub mod instances;
mod process;
pub mod ros2;

pub use attacker::send_without_reading;
pub use process::{run_to_end, Finished};

/// Path of a workspace binary built in the same profile as the running test.
///
/// `cargo test --workspace` builds every package's binaries because each binary package
/// has integration tests; they land next to the test executable's `deps/` directory.
pub fn binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target profile directory");
    let path = dir.join(name);
    assert!(
        path.exists(),
        "{} not built; run the tests with `cargo test --workspace`",
        path.display()
    );
    path
}

/// A workspace binary started as a child process with its stderr in a log file; stopped on
/// drop (SIGTERM, then SIGKILL), also when a test panics.
pub struct Process {
    child: supervise::Supervised,
    log: PathBuf,
}

impl Process {
    /// Starts `binary(name)` with `args`; stderr goes to `<scratch>/<tag>.log`.
    pub fn start(name: &str, args: &[&str], tag: &str) -> Self {
        Self::start_with_env(name, args, tag, &[])
    }

    /// [`Process::start`] with `env` added to the environment.
    pub fn start_with_env(name: &str, args: &[&str], tag: &str, env: &[(&str, String)]) -> Self {
        let log = scratch_dir("logs").join(format!("{tag}.log"));
        let mut command = std::process::Command::new(binary(name));
        command
            .envs(env.iter().map(|(k, v)| (k, v)))
            .args(args)
            .env("RUST_LOG", "info,zenoh=warn")
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::fs::File::create(&log).expect("log file"));
        let child = supervise::Supervised::spawn(&mut command, true)
            .unwrap_or_else(|e| panic!("{name} starts: {e}"))
            .with_grace(std::time::Duration::from_secs(3));
        Self { child, log }
    }

    /// What the process wrote to stderr so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// The statistics a stopped planner logged last ("final statistics stats=..."); panics
    /// with the log if there are none.
    pub fn final_statistics(&self) -> serde_json::Value {
        let log = self.log();
        let stats = log
            .lines()
            .find_map(|l| l.split_once("final statistics stats="))
            .map(|(_, s)| s.trim())
            .unwrap_or_else(|| panic!("no final statistics:\n{log}"));
        serde_json::from_str(stats).unwrap_or_else(|e| panic!("final statistics {stats}: {e}"))
    }

    /// The process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// SIGKILL: the process gets no chance to clean up.
    pub fn kill(&mut self) {
        self.child.kill();
    }

    /// SIGTERM, then waits up to `wait` for the exit; the exit status, if it exited.
    pub fn terminate(&mut self, wait: std::time::Duration) -> Option<std::process::ExitStatus> {
        self.child.terminate(wait)
    }

    /// Whether the process is still running.
    pub fn is_running(&mut self) -> bool {
        self.child.is_running()
    }
}

/// A fresh directory under the system's temp dir, unique to this test process and `name`.
pub fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hmdp-tests-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// An iceoryx2 prefix no other test (or test run) uses, so that tests cannot meet each
/// other's planners in shared memory; its files are removed when dropped.
pub struct Iceoryx2Prefix(supervise::ShmPrefix);

impl Iceoryx2Prefix {
    /// A new prefix containing `tag`.
    pub fn new(tag: &str) -> Self {
        Self(supervise::ShmPrefix::unique(&format!("hmdpt{tag}")))
    }

    /// The prefix.
    pub fn as_str(&self) -> &str {
        self.0.as_str()
    }
}

/// A free TCP port on the loopback interface (the OS picks it; it is free when returned).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// `planner serve` over Zenoh, listening on a loopback endpoint (multicast and gossip
/// scouting off), with two workers; stopped when dropped.
pub struct ZenohPlanner {
    /// The process.
    pub process: Process,
    /// Its Zenoh endpoint, e.g. `tcp/127.0.0.1:41234`.
    pub endpoint: String,
}

impl ZenohPlanner {
    /// On a free port; `extra` goes to `planner serve`.
    pub fn start(tag: &str, extra: &[&str]) -> Self {
        Self::start_at(&format!("tcp/127.0.0.1:{}", free_port()), tag, extra)
    }

    /// On `endpoint` (e.g. to restart a planner where its clients expect it).
    pub fn start_at(endpoint: &str, tag: &str, extra: &[&str]) -> Self {
        let mut args = vec!["serve", "--zenoh-listen", endpoint, "--workers", "2"];
        args.extend_from_slice(extra);
        Self {
            process: Process::start("planner", &args, tag),
            endpoint: endpoint.to_string(),
        }
    }

    /// What the planner logged so far.
    pub fn log(&self) -> String {
        self.process.log()
    }

    /// A vehicle's channel to this planner (verifying answers with `verifier`), once the
    /// planner answers; panics with the planner's log if it never does.
    pub fn vehicle(&self, verifier: Option<protocol::ResponseVerifier>) -> transport::zenoh::ZenohChannel {
        let target = transport::zenoh::ZenohTarget {
            endpoint: Some(self.endpoint.clone()),
            config_file: None,
            verifier,
            failover: Default::default(),
            insecure: false,
        };
        // Debug builds on a shared machine may take long to start answering.
        transport::zenoh::ZenohChannel::connect(&target, Duration::from_secs(60), Duration::from_secs(5))
            .unwrap_or_else(|e| panic!("planner never answered: {e}\n{}", self.log()))
    }
}

/// Sends signal `name` (e.g. `STOP`, `CONT`) to process `pid` with `kill`.
pub fn signal(pid: u32, name: &str) {
    let status = std::process::Command::new("kill")
        .args([&format!("-{name}"), &pid.to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success(), "kill -{name} {pid}");
}

pub use protocol::worked_example_request;

/// `planner keygen DIR/NAME`: the secret key file and the public one.
pub fn keygen(dir: &std::path::Path, name: &str) -> (PathBuf, PathBuf) {
    let secret = dir.join(name);
    let out = std::process::Command::new(binary("planner"))
        .arg("keygen")
        .arg(&secret)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let public = dir.join(format!("{name}.pub"));
    assert!(public.exists(), "keygen wrote no {}", public.display());
    // Refuses to overwrite an existing key.
    let again = std::process::Command::new(binary("planner"))
        .arg("keygen")
        .arg(&secret)
        .output()
        .unwrap();
    assert!(!again.status.success());
    (secret, public)
}

/// Runs `sim_client case1 --out <dir>/<name> <args>` and returns its `decisions.csv`;
/// `planner_log` is shown if the run fails.
pub fn case1_decisions(dir: &std::path::Path, name: &str, args: &[&str], planner_log: &dyn Fn() -> String) -> Vec<u8> {
    case1_decisions_with_env(dir, name, args, &[], planner_log)
}

/// [`case1_decisions`] with `env` added to `sim_client`'s environment.
pub fn case1_decisions_with_env(
    dir: &std::path::Path,
    name: &str,
    args: &[&str],
    env: &[(&str, String)],
    planner_log: &dyn Fn() -> String,
) -> Vec<u8> {
    let out = std::process::Command::new(binary("sim_client"))
        .envs(env.iter().map(|(k, v)| (k, v)))
        .args(["case1", "--out"])
        .arg(dir.join(name))
        .args(args)
        .output()
        .expect("sim_client runs");
    assert!(
        out.status.success(),
        "{name}: {}\nplanner log:\n{}",
        String::from_utf8_lossy(&out.stderr),
        planner_log()
    );
    std::fs::read(dir.join(name).join("case1/decisions.csv")).expect("decisions.csv")
}

/// `vehicles` vehicles at once, each on its own thread with its own connection
/// (`connect(vehicle)`), asking `requests` times (`ask(connection, vehicle, sequence)`):
/// every request must get a decision, each exactly once.
pub fn concurrent_vehicles_each_answered_once<C>(
    vehicles: u64,
    requests: u64,
    connect: impl Fn(u64) -> C + Sync,
    ask: impl Fn(&mut C, u64, u64) -> protocol::PlanResponse + Sync,
) {
    let mut all: Vec<(u64, u64)> = std::thread::scope(|scope| {
        let threads: Vec<_> = (1..=vehicles)
            .map(|vehicle| {
                let (connect, ask) = (&connect, &ask);
                scope.spawn(move || {
                    let mut connection = connect(vehicle);
                    (1..=requests)
                        .map(|sequence| {
                            let r = ask(&mut connection, vehicle, sequence);
                            assert!(r.outcome.as_decided().is_some(), "{r:?}");
                            (r.vehicle_id, r.sequence)
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        threads
            .into_iter()
            .flat_map(|t| t.join().expect("vehicle thread"))
            .collect()
    });
    all.sort_unstable();
    let expected: Vec<(u64, u64)> = (1..=vehicles)
        .flat_map(|v| (1..=requests).map(move |s| (v, s)))
        .collect();
    assert_eq!(all, expected);
}

/// Whether `python3` can import `modules` (as written in an `import` statement); the
/// interpreter's error when it cannot.
pub fn python_can_import(modules: &str) -> Result<(), String> {
    let out = std::process::Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .output()
        .map_err(|e| format!("python3 does not run: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(String::from_utf8_lossy(&out.stderr).into_owned())
    }
}

/// [`python_can_import`] for the tests a user may skip: a missing module fails the test (a
/// missing dependency is never a pass) with `hint`, unless HMDP_SKIP_PYTHON=1, which skips it
/// (false).
pub fn python_ready(modules: &str, hint: &str) -> bool {
    let Err(why) = python_can_import(modules) else {
        return true;
    };
    if std::env::var("HMDP_SKIP_PYTHON").as_deref() == Ok("1") {
        eprintln!("skipped: python3 cannot import {modules} and HMDP_SKIP_PYTHON=1");
        return false;
    }
    panic!("python3 cannot import {modules}: {hint}, or set HMDP_SKIP_PYTHON=1 to skip these tests\n{why}");
}

/// The shipped TLS deployment's files for one test: certificates issued by
/// `deploy/tls/make-certs` (plus a client certificate per name in `clients`) and the
/// `deploy/zenoh/` files rendered with their paths and free loopback ports.
pub struct TlsFiles {
    /// Where the certificates and the rendered files are.
    pub dir: PathBuf,
    /// The router's TLS port (the files' 7447).
    pub port: u16,
    /// The router's loopback TCP port for the planner (the files' 7448).
    pub local_port: u16,
}

impl TlsFiles {
    /// Certificates in a fresh scratch directory named after `tag`.
    pub fn new(tag: &str, clients: &[&str]) -> Self {
        let dir = scratch_dir(tag);
        let make_certs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/tls/make-certs");
        let mut command = std::process::Command::new(&make_certs);
        command.arg(dir.join("tls"));
        for c in clients {
            command.args(["--client", c]);
        }
        let out = command.output().expect("deploy/tls/make-certs runs (bash, openssl)");
        assert!(
            out.status.success(),
            "make-certs: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Self {
            dir,
            port: free_port(),
            local_port: free_port(),
        }
    }

    /// `deploy/zenoh/NAME` with this test's certificates and ports, written into the
    /// scratch directory; panics if the file holds a path or port this does not rewrite.
    pub fn render(&self, name: &str) -> PathBuf {
        let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../deploy/zenoh")
            .join(name);
        let text = std::fs::read_to_string(&shipped).expect("shipped configuration");
        let port = self.port;
        let rendered = text
            .replace("/etc/hmdp/tls/", &format!("{}/", self.dir.join("tls").display()))
            .replace("tls/0.0.0.0:7447", &format!("tls/127.0.0.1:{port}"))
            .replace("tls/localhost:7447", &format!("tls/localhost:{port}"))
            .replace("tls/hmdp-router:7447", &format!("tls/127.0.0.1:{port}"))
            .replace("tcp/127.0.0.1:7448", &format!("tcp/127.0.0.1:{}", self.local_port));
        let mut active = rendered.lines().filter(|l| !l.trim_start().starts_with("//"));
        assert!(
            active.all(|l| !l.contains("/etc/hmdp") && !l.contains(":7447") && !l.contains(":7448")),
            "{name} no longer matches what the tests rewrite"
        );
        let path = self.dir.join(name);
        std::fs::write(&path, rendered).expect("rendered configuration");
        path
    }

    /// The path of a certificate or key file, e.g. `vehicle.pem`.
    pub fn cert(&self, file: &str) -> PathBuf {
        self.dir.join("tls").join(file)
    }
}

/// What a normal vehicle got for its requests while the network was under attack.
#[derive(Debug, Default)]
pub struct VictimFigures {
    pub sent: u64,
    /// Its own answer (vehicle id and sequence match) within a second.
    pub answered: u64,
    /// Of those, watchdog fallbacks (the planner did not decide in time, or refused to queue).
    pub watchdog: u64,
}

/// A normal vehicle (id 7) over Zenoh: `requests` requests at 20 Hz, each waited for up to
/// 1 s; stops early if `alive` (asked every 20 requests) says a server process died.
pub fn normal_vehicle(
    channel: &transport::zenoh::ZenohChannel,
    requests: u64,
    alive: impl FnMut() -> bool,
) -> VictimFigures {
    use protocol::{decode_bincode, encode_bincode, PlanResponse, WireFormat};
    let ask = |request: &protocol::PlanRequest| {
        let replies = channel.ask_raw(&encode_bincode(request), WireFormat::Bincode, VICTIM_WAIT);
        replies
            .iter()
            .filter_map(|(bytes, _)| decode_bincode::<PlanResponse>(bytes).ok())
            .find(|r| (r.vehicle_id, r.sequence) == (request.vehicle_id, request.sequence))
    };
    normal_vehicle_asking(ask, requests, alive)
}

/// How long the normal vehicle waits for each answer.
pub const VICTIM_WAIT: Duration = Duration::from_secs(1);

/// The normal vehicle on any transport: `ask` sends one request and returns its own answer
/// if one came within [`VICTIM_WAIT`].
pub fn normal_vehicle_asking(
    mut ask: impl FnMut(&protocol::PlanRequest) -> Option<protocol::PlanResponse>,
    requests: u64,
    mut alive: impl FnMut() -> bool,
) -> VictimFigures {
    use protocol::Layer;
    let mut figures = VictimFigures::default();
    for sequence in 1..=requests {
        if sequence % 20 == 0 && !alive() {
            break;
        }
        let started = std::time::Instant::now();
        let mut request = worked_example_request(7, sequence);
        request.deadline_us = 380_000;
        figures.sent += 1;
        if let Some(response) = ask(&request) {
            figures.answered += 1;
            let layer = response.outcome.as_decided().and_then(|d| d.layer().ok());
            if layer == Some(Layer::WatchdogFallback) {
                figures.watchdog += 1;
            }
        }
        std::thread::sleep(Duration::from_millis(50).saturating_sub(started.elapsed()));
    }
    figures
}
