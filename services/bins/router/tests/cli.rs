//! `hmdp-router` as a process: it routes between two client sessions, refuses a
//! configuration written for another mode, and stops cleanly on SIGTERM.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use zenoh::Wait;

const ROUTER: &str = env!("CARGO_BIN_EXE_hmdp-router");
/// Startup on a loaded machine.
const STARTUP: Duration = Duration::from_secs(30);

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hmdp-router-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

fn write(path: &PathBuf, text: &str) {
    std::fs::File::create(path).unwrap().write_all(text.as_bytes()).unwrap();
}

/// The router child, killed on drop (also when an assertion fails).
struct Router {
    child: Child,
    log: PathBuf,
}

impl Router {
    fn start(config: &PathBuf, listen: &str, log: PathBuf) -> Self {
        let child = Command::new(ROUTER)
            .arg("--config")
            .arg(config)
            .args(["--listen", listen])
            .env("RUST_LOG", "info,zenoh=warn")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .expect("hmdp-router starts");
        let router = Self { child, log };
        let give_up = Instant::now() + STARTUP;
        while !router.log().contains("router running") {
            assert!(Instant::now() < give_up, "router not running:\n{}", router.log());
            std::thread::sleep(Duration::from_millis(50));
        }
        router
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for Router {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn client(endpoint: &str) -> zenoh::Session {
    let json = serde_json::json!({
        "mode": "client",
        "connect": { "endpoints": [endpoint] },
        "scouting": { "multicast": { "enabled": false } },
    });
    let config = zenoh::Config::from_json5(&json.to_string()).unwrap();
    zenoh::open(config).wait().expect("client session")
}

#[test]
fn routes_queries_between_clients_and_stops_on_sigterm() {
    let dir = scratch("route");
    let config = dir.join("router.json5");
    // The file's endpoint is replaced by --listen.
    write(
        &config,
        r#"{ mode: "router", listen: { endpoints: ["tcp/127.0.0.1:1"] }, scouting: { multicast: { enabled: false } } }"#,
    );
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut router = Router::start(&config, &endpoint, dir.join("router.log"));

    let server = client(&endpoint);
    let _queryable = server
        .declare_queryable("hmdp/test/echo")
        .callback(|query| {
            let key = query.key_expr().clone();
            let _ = query.reply(key, "pong").wait();
        })
        .wait()
        .unwrap();
    let asker = client(&endpoint);
    // The queryable's declaration reaches the router asynchronously: ask until it answers.
    let give_up = Instant::now() + STARTUP;
    let answer = loop {
        let replies = asker
            .get("hmdp/test/echo")
            .timeout(Duration::from_millis(500))
            .wait()
            .unwrap();
        if let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                break sample.payload().try_to_string().unwrap().into_owned();
            }
        }
        assert!(
            Instant::now() < give_up,
            "no answer through the router:\n{}",
            router.log()
        );
    };
    assert_eq!(answer, "pong");

    let pid = router.child.id().to_string();
    assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    let give_up = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(status) = router.child.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < give_up, "router ignores SIGTERM:\n{}", router.log());
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status}:\n{}", router.log());
    assert!(router.log().contains("stopped"), "{}", router.log());
}

#[test]
fn refuses_a_configuration_for_another_mode() {
    let dir = scratch("mode");
    let config = dir.join("client.json5");
    write(
        &config,
        r#"{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:7447"] } }"#,
    );
    let out = Command::new(ROUTER)
        .arg("--config")
        .arg(&config)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("runs only as a router"), "{stderr}");
}

#[test]
fn reports_an_unreadable_configuration() {
    let out = Command::new(ROUTER)
        .args(["--config", "/nonexistent/router.json5"])
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("/nonexistent/router.json5"), "{stderr}");
}
