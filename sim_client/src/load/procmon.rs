//! CPU and RSS of a process, sampled from `/proc`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// One sample of the planner process.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct ProcessSample {
    /// Time since the start, s.
    pub t_s: f64,
    /// CPU use since the previous sample, % of one core.
    pub cpu_percent: f64,
    /// Resident set size, KiB.
    pub rss_kib: u64,
}

/// The planner process over the run.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ProcessReport {
    /// Process id.
    pub pid: u32,
    /// The samples.
    pub samples: Vec<ProcessSample>,
    /// RSS at the first sample after the warm-up.
    pub rss_after_warmup_kib: u64,
    /// Largest RSS after the warm-up.
    pub rss_max_after_warmup_kib: u64,
    /// `(rss_max_after_warmup - rss_after_warmup) / rss_after_warmup`, %.
    pub rss_growth_percent: f64,
    /// Mean CPU use over the run, % of one core.
    pub cpu_mean_percent: f64,
}

impl ProcessReport {
    /// The report of `samples`, with RSS growth measured after `warmup`.
    pub fn of(pid: u32, samples: Vec<ProcessSample>, warmup: Duration) -> Self {
        let after: Vec<&ProcessSample> = samples.iter().filter(|s| s.t_s >= warmup.as_secs_f64()).collect();
        let base = after.first().map_or(0, |s| s.rss_kib);
        let max = after.iter().map(|s| s.rss_kib).max().unwrap_or(0);
        let cpu_mean_percent = if samples.is_empty() {
            0.0
        } else {
            samples.iter().map(|s| s.cpu_percent).sum::<f64>() / samples.len() as f64
        };
        Self {
            pid,
            rss_after_warmup_kib: base,
            rss_max_after_warmup_kib: max,
            rss_growth_percent: if base > 0 {
                100.0 * (max.saturating_sub(base)) as f64 / base as f64
            } else {
                0.0
            },
            cpu_mean_percent,
            samples,
        }
    }
}

/// Samples a process's CPU and RSS from `/proc` every `period` until stopped.
pub struct ProcessMonitor {
    stop: Arc<AtomicBool>,
    samples: Arc<Mutex<Vec<ProcessSample>>>,
    thread: Option<std::thread::JoinHandle<()>>,
    pid: u32,
}

/// (utime + stime in clock ticks, RSS in KiB) of `pid`.
fn read_proc(pid: u32) -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name may contain spaces; fields count from after its closing parenthesis.
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: u64 = fields.get(11)?.parse().ok()?;
    let stime: u64 = fields.get(12)?.parse().ok()?;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let rss = status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some((utime + stime, rss))
}

impl ProcessMonitor {
    /// Starts sampling `pid`.
    pub fn start(pid: u32, period: Duration) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let samples = Arc::new(Mutex::new(Vec::new()));
        let (s, out) = (Arc::clone(&stop), Arc::clone(&samples));
        // SAFETY: sysconf has no preconditions.
        let ticks_per_s = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
        let thread = std::thread::spawn(move || {
            let start = Instant::now();
            let mut last = read_proc(pid).map(|(cpu, _)| (Instant::now(), cpu));
            while !s.load(Ordering::Relaxed) {
                std::thread::sleep(period);
                let Some((cpu, rss)) = read_proc(pid) else { break };
                let now = Instant::now();
                let cpu_percent = match last {
                    Some((t, c)) => 100.0 * (cpu.saturating_sub(c) as f64 / ticks_per_s) / (now - t).as_secs_f64(),
                    None => 0.0,
                };
                last = Some((now, cpu));
                out.lock().unwrap_or_else(|e| e.into_inner()).push(ProcessSample {
                    t_s: start.elapsed().as_secs_f64(),
                    cpu_percent,
                    rss_kib: rss,
                });
            }
        });
        Self {
            stop,
            samples,
            thread: Some(thread),
            pid,
        }
    }

    /// Stops sampling; the report, with RSS growth measured after `warmup`.
    pub fn finish(mut self, warmup: Duration) -> ProcessReport {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let samples = std::mem::take(&mut *self.samples.lock().unwrap_or_else(|e| e.into_inner()));
        ProcessReport::of(self.pid, samples, warmup)
    }
}
