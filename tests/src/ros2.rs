//! What the ROS 2 tests share: the venv with a real ROS 2 (rclpy on Fast DDS, hmdp_msgs)
//! that `scripts/ros2-env` builds, a DDS domain per test, and the rclpy tool
//! `clients/ros2/hmdp_ros2_client.py`.

use std::path::PathBuf;
use std::process::{Command, Output};

/// The venv: `HMDP_ROS2_VENV`, by default `<workspace>/target/ros2-venv`. Missing is a
/// failure, not a skip: CI builds it, and a test that passes without running proves nothing.
pub fn venv() -> PathBuf {
    let path = std::env::var_os("HMDP_ROS2_VENV").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/ros2-venv"),
        PathBuf::from,
    );
    assert!(
        path.join("bin/python").exists(),
        "no ROS 2 venv at {}: build it with `scripts/ros2-env target/ros2-venv` (scripts/install-build-deps does)",
        path.display()
    );
    path
}

/// A DDS domain of its own for one test (`slot` distinguishes the tests of one process), and
/// discovery on this host only. Domains 100..=230 are the tests'; the slot and this process's
/// id pick one, so that concurrent test processes rarely meet.
#[derive(Debug, Clone)]
pub struct Domain(u16);

impl Domain {
    /// The domain of test `slot` (0..8).
    pub fn new(slot: u16) -> Self {
        Self(100 + ((std::process::id() as u16 % 16) * 8 + slot) % 131)
    }

    /// The domain's id.
    pub fn id(&self) -> u16 {
        self.0
    }

    /// The environment every ROS 2 process of the test gets.
    pub fn env(&self) -> [(&'static str, String); 3] {
        [
            ("ROS_DOMAIN_ID", self.0.to_string()),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST".to_owned()),
            // rclpy writes a log file per process; not into the user's home.
            ("ROS_LOG_DIR", crate::scratch_dir("ros-log").display().to_string()),
        ]
    }

    /// A Rust ROS 2 vehicle (node `hmdp_<role>_<pid>`) on this domain, loopback discovery,
    /// its planner's service matched and answering within `startup` (`planner`'s log in the
    /// panic otherwise).
    pub fn plan_client(
        &self,
        role: &str,
        planner: &crate::Process,
        startup: std::time::Duration,
    ) -> hmdp_ros2::PlanClient {
        let client = hmdp_ros2::PlanClient::new(hmdp_ros2::ClientOptions {
            node: hmdp_ros2::NodeConfig {
                domain_id: Some(self.0),
                discovery: Some(hmdp_ros2::DiscoveryRange::Localhost),
                ..hmdp_ros2::NodeConfig::named(format!("hmdp_{role}_{}", std::process::id()))
            },
        })
        .expect("a ROS 2 client");
        client
            .wait_for_service(startup)
            .unwrap_or_else(|e| panic!("{role}: {e}\n{}", planner.log()));
        client
    }

    /// A command with this domain's environment.
    pub fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut command = Command::new(program);
        command.envs(self.env());
        command
    }
}

/// `clients/ros2/hmdp_ros2_client.py ARGS` with the venv's python on `domain`: its JSON
/// report and the whole output (shown when an assertion fails).
pub fn rclpy_client(domain: &Domain, args: &[&str]) -> (serde_json::Value, Output) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../clients/ros2/hmdp_ros2_client.py");
    let out = domain
        .command(venv().join("bin/python"))
        .arg(&script)
        .args(args)
        .output()
        .expect("the venv's python runs");
    let report = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "hmdp_ros2_client.py {args:?} printed no JSON ({e}): {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (report, out)
}
