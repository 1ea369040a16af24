//! A `planner serve` process started for a run (`--spawn-planner`): found next to this
//! executable, dying with this process, stopped when dropped.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use supervise::{ShmPrefix, Supervised};

use crate::error::{Result, SimClientError};

/// What the planner serves.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Serve {
    /// iceoryx2 under a prefix; `None` makes one up that no other planner uses, and removes
    /// its files at the end.
    Iceoryx2 {
        /// The prefix to serve under.
        prefix: Option<String>,
        /// `--busy-poll` of the planner.
        busy_poll: bool,
    },
    /// Zenoh, listening on a free loopback port.
    Zenoh,
    /// A ROS 2 node, on the domain and discovery range this process's environment names.
    Ros2,
}

/// A started planner and where it is reached.
pub struct SpawnedPlanner {
    /// The process (stopped when dropped).
    pub process: Supervised,
    /// The iceoryx2 prefix, for [`Serve::Iceoryx2`].
    pub iceoryx2_prefix: Option<String>,
    /// The Zenoh endpoint, for [`Serve::Zenoh`].
    pub zenoh_endpoint: Option<String>,
}

/// How to start it.
#[derive(Debug, Clone, Default)]
pub struct SpawnOptions {
    /// `--workers` of the planner.
    pub workers: Option<usize>,
    /// `--config` of the planner.
    pub config: Option<PathBuf>,
    /// Where its stderr goes (inherited when `None`).
    pub log: Option<PathBuf>,
    /// `--record` of the planner: it records every request and answer to this MCAP file.
    pub record: Option<PathBuf>,
}

/// How long a recording planner may take to complete its file when stopped (it writes what
/// is queued and the MCAP summary); other planners get the default.
const RECORDING_GRACE: std::time::Duration = std::time::Duration::from_secs(30);

/// Starts `planner serve` for `serve`.
pub fn spawn_planner(serve: &Serve, options: &SpawnOptions) -> Result<SpawnedPlanner> {
    let exe = std::env::current_exe().map_err(|e| SimClientError::io("sim_client's executable", e))?;
    let planner = planner_next_to(&exe);
    let mut cmd = Command::new(&planner);
    cmd.arg("serve").stdin(Stdio::null());
    let (mut owned, mut iceoryx2_prefix, mut zenoh_endpoint) = (None, None, None);
    match serve {
        Serve::Iceoryx2 { prefix, busy_poll } => {
            // A prefix of its own, so that it cannot meet another planner on this machine;
            // only a prefix this run made up is ours to clean.
            let prefix = match prefix {
                Some(p) => p.clone(),
                None => owned.insert(ShmPrefix::unique("hmdp")).as_str().to_owned(),
            };
            cmd.args(["--iceoryx2", "--iceoryx2-prefix", &prefix]);
            if *busy_poll {
                cmd.arg("--busy-poll");
            }
            iceoryx2_prefix = Some(prefix);
        }
        Serve::Zenoh => {
            let port = free_port().map_err(|e| SimClientError::io("a loopback port", e))?;
            let endpoint = format!("tcp/127.0.0.1:{port}");
            cmd.args(["--zenoh-listen", &endpoint]);
            zenoh_endpoint = Some(endpoint);
        }
        Serve::Ros2 => {
            cmd.arg("--ros2");
        }
    }
    if let Some(w) = options.workers {
        cmd.arg("--workers").arg(w.to_string());
    }
    if let Some(p) = &options.config {
        cmd.arg("--config").arg(p);
    }
    if let Some(file) = &options.record {
        cmd.arg("--record").arg(file);
    }
    if let Some(log) = &options.log {
        cmd.stderr(std::fs::File::create(log).map_err(|e| SimClientError::io(log, e))?);
    }
    let mut process = Supervised::spawn(&mut cmd, true).map_err(|e| SimClientError::io(&planner, e))?;
    if let Some(prefix) = owned {
        process = process.owning(prefix);
    }
    if options.record.is_some() {
        process = process.with_grace(RECORDING_GRACE);
    }
    Ok(SpawnedPlanner {
        process,
        iceoryx2_prefix,
        zenoh_endpoint,
    })
}

/// A free TCP port on the loopback interface (the OS picks it; free when returned).
pub fn free_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// The planner binary next to `exe`.
pub fn planner_next_to(exe: &Path) -> PathBuf {
    exe.with_file_name(format!("planner{}", std::env::consts::EXE_SUFFIX))
}
