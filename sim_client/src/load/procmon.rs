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
    /// Median RSS over the first quarter of the samples after the warm-up.
    pub rss_after_warmup_kib: u64,
    /// Median RSS over the last quarter of the samples after the warm-up.
    pub rss_end_kib: u64,
    /// Largest RSS after the warm-up.
    pub rss_max_after_warmup_kib: u64,
    /// `(rss_end - rss_after_warmup) / rss_after_warmup`, %: the trend. Medians, not the
    /// first sample against the largest, because the allocator's working set breathes by a
    /// few per cent under a steady load (up 1.4 MiB and back within a minute) and a leak is
    /// what keeps growing.
    pub rss_growth_percent: f64,
    /// Mean CPU use over the run, % of one core.
    pub cpu_mean_percent: f64,
}

impl ProcessReport {
    /// The report of `samples`, with RSS growth measured after `warmup`.
    pub fn of(pid: u32, samples: Vec<ProcessSample>, warmup: Duration) -> Self {
        let after: Vec<u64> = samples
            .iter()
            .filter(|s| s.t_s >= warmup.as_secs_f64())
            .map(|s| s.rss_kib)
            .collect();
        let quarter = after.len().div_ceil(4);
        let base = median(&after[..quarter]);
        let end = median(&after[after.len() - quarter..]);
        let max = after.iter().copied().max().unwrap_or(0);
        let cpu_mean_percent = if samples.is_empty() {
            0.0
        } else {
            samples.iter().map(|s| s.cpu_percent).sum::<f64>() / samples.len() as f64
        };
        Self {
            pid,
            rss_after_warmup_kib: base,
            rss_end_kib: end,
            rss_max_after_warmup_kib: max,
            rss_growth_percent: if base > 0 {
                100.0 * (end.saturating_sub(base)) as f64 / base as f64
            } else {
                0.0
            },
            cpu_mean_percent,
            samples,
        }
    }
}

/// Median of `values` (0 when empty; the upper middle of an even count).
fn median(values: &[u64]) -> u64 {
    let mut v = values.to_vec();
    v.sort_unstable();
    v.get(v.len() / 2).copied().unwrap_or(0)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(rss: &[u64]) -> Vec<ProcessSample> {
        rss.iter()
            .enumerate()
            .map(|(i, &rss_kib)| ProcessSample {
                t_s: i as f64,
                cpu_percent: 10.0,
                rss_kib,
            })
            .collect()
    }

    #[test]
    fn a_passing_peak_is_not_growth_but_a_trend_is() {
        // Warm-up 2 s; after it 8 samples, quarters of 2.
        let breathing = ProcessReport::of(
            1,
            samples(&[10, 20, 100, 100, 107, 107, 100, 100, 101, 100]),
            Duration::from_secs(2),
        );
        assert_eq!((breathing.rss_after_warmup_kib, breathing.rss_end_kib), (100, 101));
        assert_eq!(breathing.rss_max_after_warmup_kib, 107);
        assert!((breathing.rss_growth_percent - 1.0).abs() < 1e-9);
        let leak = ProcessReport::of(
            1,
            samples(&[10, 20, 100, 101, 102, 103, 104, 105, 106, 107]),
            Duration::from_secs(2),
        );
        assert_eq!((leak.rss_after_warmup_kib, leak.rss_end_kib), (101, 107));
        assert!((leak.rss_growth_percent - 100.0 * 6.0 / 101.0).abs() < 1e-9);
    }
}
