//! What every binary of the project does the same way.
//!
//! * [`init_process`]: SIGPIPE back to its default and logging to stderr;
//!   [`ignore_sigpipe`] for the services.
//! * [`termination_signal`]: SIGINT or SIGTERM, for the services.
//! * [`planner_config`]: the planner's TOML configuration file, or the defaults.
//! * [`Supervised`]: a child process that stops (SIGTERM, then SIGKILL) when dropped and can
//!   be made to die with its parent; [`ShmPrefix`]: an iceoryx2 prefix whose files are
//!   removed when dropped.

mod child;

pub use child::{ShmPrefix, Supervised};

use std::path::{Path, PathBuf};

use decision::PlannerConfig;
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

/// Why the planner configuration could not be loaded.
#[derive(Debug, Error)]
pub enum ConfigFileError {
    #[error("reading the planner configuration {path}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("planner configuration {path}")]
    Parse {
        path: PathBuf,
        #[source]
        source: decision::ConfigError,
    },
}

/// The planner configuration in the TOML file at `path`, or the defaults without one.
pub fn planner_config(path: Option<&Path>) -> Result<PlannerConfig, ConfigFileError> {
    let Some(path) = path else {
        return Ok(PlannerConfig::default());
    };
    let text = std::fs::read_to_string(path).map_err(|source| ConfigFileError::Read {
        path: path.to_owned(),
        source,
    })?;
    PlannerConfig::from_toml_str(&text).map_err(|source| ConfigFileError::Parse {
        path: path.to_owned(),
        source,
    })
}
