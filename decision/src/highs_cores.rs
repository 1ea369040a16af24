//! A cached answer to HiGHS's "how many physical cores?" question.
//!
//! HiGHS 1.13 (`highs-sys` 1.16) asks `highs::parallel::available_core_count()` on every
//! `Highs_run`, for a log line: on Linux that is `sysconf(_SC_NPROCESSORS_CONF)` (a directory
//! listing of `/sys/devices/system/cpu`) and two sysfs files opened, read and closed per CPU.
//! The planner runs HiGHS on LPs that take microseconds, many times per decision, and that
//! question was a third of the time of each `Highs_run` (perf, `planner bench` at H = 3).
//!
//! `.cargo/config.toml` links every binary of this workspace with
//! `--wrap=_ZN5highs8parallel20available_core_countEv`: HiGHS's calls then land here, where the
//! count is computed once per process. A binary linked without that flag never calls this
//! function and keeps HiGHS's own (same answer, just slower). HiGHS uses the number only for
//! its log and for the thread count when `threads` is 0; the planner sets `threads = 1`.

use std::sync::OnceLock;

/// The count, set by HiGHS's first call (a test checks that it is, i.e. that the wrap is in
/// effect).
static CORES: OnceLock<u32> = OnceLock::new();

/// The wrapped symbol's replacement (C ABI, the name `--wrap` gives it).
#[no_mangle]
pub extern "C" fn __wrap__ZN5highs8parallel20available_core_countEv() -> u32 {
    *CORES.get_or_init(physical_cores)
}

/// Nearly HiGHS's own answer: the distinct (package, core) pairs of the machine's CPUs (HiGHS
/// counts only those of the process's affinity set), or half the logical CPUs when the
/// topology cannot be read.
fn physical_cores() -> u32 {
    let logical = std::thread::available_parallelism().map_or(1, |n| n.get());
    let fallback = logical.div_ceil(2) as u32;
    let Ok(entries) = std::fs::read_dir("/sys/devices/system/cpu") else {
        return fallback;
    };
    let mut cores = std::collections::BTreeSet::new();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(index) = name.to_str().and_then(|n| n.strip_prefix("cpu")) else {
            continue;
        };
        if index.is_empty() || !index.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let topology = entry.path().join("topology");
        let read = |file: &str| std::fs::read_to_string(topology.join(file)).ok();
        match (read("physical_package_id"), read("core_id")) {
            (Some(package), Some(core)) => {
                cores.insert((package.trim().to_owned(), core.trim().to_owned()));
            }
            _ => return fallback,
        }
    }
    match cores.len() {
        0 => fallback,
        n => n as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::highs_solver::{HighsSolver, MipModel};

    #[test]
    fn highs_asks_here_for_its_core_count() {
        let mut model = MipModel::default();
        let x = model.add_col(1.0, 0.0, 1.0, false);
        model.add_row(0.5, f64::INFINITY, &mut [(x, 1.0)]);
        // Nothing in this crate calls the replacement itself: only HiGHS, through the wrap.
        HighsSolver::new(1.0).unwrap().solve(&model, None).unwrap();
        assert!(
            CORES.get().is_some(),
            "HiGHS computed its core count itself: the binary was linked without the \
             --wrap flag of .cargo/config.toml"
        );
        assert!(CORES.get().is_some_and(|&n| n >= 1));
    }
}
