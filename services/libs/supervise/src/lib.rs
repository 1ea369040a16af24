//! What every binary of the project does the same way.
//!
//! * [`init_process`]: SIGPIPE back to its default and logging to stderr;
//!   [`ignore_sigpipe`] for the services.
//! * [`termination_signal`]: SIGINT or SIGTERM, for the services.
//! * [`set_thread_nice`], [`set_thread_realtime`]: a thread's scheduling priority.
//! * [`Supervised`]: a child process that stops (SIGTERM, then SIGKILL) when dropped and can
//!   be made to die with its parent; [`ShmPrefix`]: an iceoryx2 prefix whose files are
//!   removed when dropped.

mod child;

pub use child::{ShmPrefix, Supervised};

use thiserror::Error;

/// Makes a closed stdout end the process quietly (`... | head`), as command-line tools do,
/// instead of a panic in `println!`, and logs to stderr: `RUST_LOG` or `default_filter`
/// (e.g. `info,zenoh=warn`), colours only on a terminal (journald and log files get plain
/// text). Call it first in `main`, before any thread exists.
pub fn init_process(default_filter: &str) {
    // SAFETY: resets a signal disposition; no other thread exists yet.
    #[cfg(unix)]
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL)
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_filter)),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
}

/// Ignores SIGPIPE, for the long-running services: a peer that closes its socket while an
/// answer is being written must cost that write an `EPIPE` error, never the process. Call it
/// right after [`init_process`], before any thread exists.
pub fn ignore_sigpipe() {
    // SAFETY: sets a signal disposition; no other thread exists yet.
    #[cfg(unix)]
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN)
    };
}

/// Sets the calling thread's nice value (Linux schedules threads one by one; raising it
/// needs no privilege). The planner's solver threads run at a lower priority than its
/// watchdog and its transports, so that on a busy machine a deadline answer or a reply is not
/// kept waiting behind a solve. A no-op elsewhere.
pub fn set_thread_nice(nice: i32) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: gettid and setpriority concern only the calling thread.
        let result = unsafe { libc::setpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t, nice) };
        if result != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = nice;
    Ok(())
}

/// Why the calling thread could not be given a real-time priority.
#[derive(Debug, Error)]
pub enum RealtimeError {
    #[error("real-time priority {priority} is outside SCHED_FIFO's range {min}..={max}")]
    OutOfRange { priority: i32, min: i32, max: i32 },
    #[error(
        "SCHED_FIFO priority {priority} not permitted: needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at \
         least {priority} (systemd: AmbientCapabilities=CAP_SYS_NICE or LimitRTPRIO={priority})"
    )]
    NotPermitted {
        priority: i32,
        #[source]
        source: std::io::Error,
    },
    #[error("sched_setscheduler(SCHED_FIFO, {priority})")]
    Os {
        priority: i32,
        #[source]
        source: std::io::Error,
    },
    #[error("real-time priorities are supported on Linux only")]
    Unsupported,
}

/// Puts the calling thread in the SCHED_FIFO class at `priority` (1..=99): it then runs as
/// soon as it is runnable, ahead of every ordinary thread, instead of waiting for a core
/// behind them. For short wake-ups only (the planner's deadline watchdog): a real-time
/// thread that computes starves the ordinary ones on its core (the kernel keeps 5% of each
/// second for them, `kernel.sched_rt_runtime_us`). Processes the thread starts do not inherit
/// the class (`SCHED_RESET_ON_FORK`).
pub fn set_thread_realtime(priority: i32) -> Result<(), RealtimeError> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: plain queries of the scheduler's constants.
        let (min, max) = unsafe {
            (
                libc::sched_get_priority_min(libc::SCHED_FIFO),
                libc::sched_get_priority_max(libc::SCHED_FIFO),
            )
        };
        if !(min..=max).contains(&priority) {
            return Err(RealtimeError::OutOfRange { priority, min, max });
        }
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: pid 0 is the calling thread; `param` outlives the call.
        let result = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK, &param) };
        if result != 0 {
            let source = std::io::Error::last_os_error();
            return Err(match source.raw_os_error() {
                Some(libc::EPERM) => RealtimeError::NotPermitted { priority, source },
                _ => RealtimeError::Os { priority, source },
            });
        }
        Ok(())
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = priority;
        Err(RealtimeError::Unsupported)
    }
}

/// Hands the allocator's free memory back to the system (glibc keeps freed heap pages,
/// so a service's RSS would otherwise stay at its high-water mark, and a soak could not
/// tell a leak from one large request). A no-op elsewhere.
pub fn release_free_memory() {
    // SAFETY: malloc_trim only releases memory the allocator holds free.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Resolves on the first SIGINT or SIGTERM (systemd stops services with SIGTERM).
pub async fn termination_signal() {
    use tokio::signal::unix::{signal, SignalKind};
    let mut term = match signal(SignalKind::terminate()) {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cannot watch SIGTERM: {e}");
            let _ = tokio::signal::ctrl_c().await;
            return;
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => tracing::info!("SIGINT"),
        _ = term.recv() => tracing::info!("SIGTERM"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calling thread's scheduling class and real-time priority: `(SCHED_FIFO, 10)`, or
    /// `(SCHED_OTHER, 0)` for an ordinary thread.
    #[cfg(target_os = "linux")]
    fn thread_scheduler() -> Option<(i32, i32)> {
        let mut param = libc::sched_param { sched_priority: 0 };
        // SAFETY: pid 0 is the calling thread; `param` outlives the call.
        let (policy, result) = unsafe { (libc::sched_getscheduler(0), libc::sched_getparam(0, &mut param)) };
        (policy >= 0 && result == 0).then_some((policy & !libc::SCHED_RESET_ON_FORK, param.sched_priority))
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_thread_gets_a_real_time_priority_or_a_typed_refusal() {
        // On a thread of its own: the class stays with the thread, and the thread ends.
        std::thread::spawn(|| {
            assert!(matches!(
                set_thread_realtime(1000),
                Err(RealtimeError::OutOfRange { priority: 1000, .. })
            ));
            assert_eq!(thread_scheduler(), Some((libc::SCHED_OTHER, 0)));
            match set_thread_realtime(1) {
                Ok(()) => assert_eq!(thread_scheduler(), Some((libc::SCHED_FIFO, 1))),
                // Unprivileged, without an RLIMIT_RTPRIO: refused, and the thread unchanged.
                Err(e) => {
                    assert!(matches!(e, RealtimeError::NotPermitted { priority: 1, .. }), "{e}");
                    assert_eq!(thread_scheduler(), Some((libc::SCHED_OTHER, 0)));
                }
            }
        })
        .join()
        .unwrap();
    }
}
