//! `load --processes N`: the vehicles shared among N `sim_client load-worker` children, whose
//! parts are merged.

use std::path::{Path, PathBuf};

use transport::iceoryx2::WaitMode;

use super::report::LoadPart;
use super::LoadSettings;
use crate::connect::Transport;
use crate::error::{Result, SimClientError};

/// The command-line flags that reach `transport` (for the children).
pub fn transport_flags(transport: &Transport) -> Vec<String> {
    let mut flags = vec!["--transport".to_string(), transport.to_string()];
    match transport {
        Transport::InProcess => {}
        Transport::Iceoryx2 { prefix, wait, verifier } => {
            if let Some(p) = prefix {
                flags.extend(["--iceoryx2-prefix".into(), p.clone()]);
            }
            if let WaitMode::BusyPoll { .. } = wait {
                flags.push("--busy-poll".into());
            }
            if let Some(v) = verifier {
                flags.extend(["--planner-public-key".into(), v.to_hex()]);
            }
        }
        Transport::Ros2 { verifier } => {
            if let Some(v) = verifier {
                flags.extend(["--planner-public-key".into(), v.to_hex()]);
            }
        }
        Transport::Zenoh(target) => {
            if let Some(e) = &target.endpoint {
                flags.extend(["--zenoh-connect".into(), e.clone()]);
            }
            if let Some(f) = &target.config_file {
                flags.extend(["--zenoh-config".into(), f.display().to_string()]);
            }
            if let Some(v) = &target.verifier {
                flags.extend(["--planner-public-key".into(), v.to_hex()]);
            }
            if target.insecure {
                flags.push("--insecure".into());
            }
            let failover = &target.failover;
            for (flag, d) in [
                ("--zenoh-retry-after", failover.retry_after),
                ("--zenoh-suspect-for", failover.suspect_for),
            ] {
                flags.extend([flag.into(), format!("{}ms", d.as_millis())]);
            }
        }
    }
    flags
}

/// How many children `load --processes processes` starts for `clients` vehicles.
pub fn worker_count(clients: usize, processes: usize) -> usize {
    processes.min(clients).max(1)
}

/// The recording of child `worker` of `load --processes N --record BASE`: each child records
/// its own vehicles, to `BASE.worker0.mcap`, `BASE.worker1.mcap`, ...
pub fn worker_record_path(base: &Path, worker: usize) -> PathBuf {
    crate::recorded::suffixed(base, &format!("worker{worker}"))
}

/// Runs `settings.clients` vehicles in `processes` children of this executable (each gets
/// its share), the planner configuration from `planner_config`, each recording to
/// [`worker_record_path`] when `record` is given; their parts.
pub fn run_worker_processes(
    settings: &LoadSettings,
    processes: usize,
    planner_config: Option<&Path>,
    record: Option<&Path>,
) -> Result<Vec<LoadPart>> {
    let exe = std::env::current_exe().map_err(|e| SimClientError::io("sim_client's executable", e))?;
    let dir = std::env::temp_dir().join(format!("hmdp-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| SimClientError::io(&dir, e))?;
    let n = worker_count(settings.clients, processes);
    let mut children = Vec::new();
    let mut base = settings.vehicle_id_base;
    for i in 0..n {
        let clients = settings.clients / n + usize::from(i < settings.clients % n);
        let out = dir.join(format!("part-{i}.json"));
        let mut cmd = std::process::Command::new(&exe);
        cmd.arg("load-worker")
            .args(transport_flags(&settings.transport))
            .args(["--clients", &clients.to_string()])
            .args(["--rate", &settings.rate_hz.to_string()])
            .args(["--duration", &format!("{}ms", settings.duration.as_millis())])
            .args(["--deadline-ms", &settings.deadline.as_millis().to_string()])
            .args(["--seed", &settings.seed.to_string()])
            .args(["--vehicle-id-base", &base.to_string()])
            .arg("--part-out")
            .arg(&out);
        if let Some(p) = planner_config {
            cmd.arg("--planner-config").arg(p);
        }
        if let Some(base) = record {
            cmd.arg("--record").arg(worker_record_path(base, i));
        }
        let child = supervise::Supervised::spawn(&mut cmd, true).map_err(|e| SimClientError::io(&exe, e))?;
        children.push((child, out));
        base += clients as u64;
    }
    let mut parts = Vec::new();
    for (mut child, out) in children {
        let status = child.wait().map_err(|e| SimClientError::io(&exe, e))?;
        if !status.success() {
            return Err(SimClientError::Config(format!("a load worker failed ({status})")));
        }
        let text = std::fs::read_to_string(&out).map_err(|e| SimClientError::io(&out, e))?;
        parts.push(serde_json::from_str(&text)?);
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(parts)
}
