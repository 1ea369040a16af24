//! Errors of the simulation client library.

use thiserror::Error;

use crate::link::LinkError;

/// Anything that can stop an experiment.
#[derive(Debug, Error)]
pub enum SimClientError {
    /// The planner link failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The simulator rejected a scenario, parameter or command.
    #[error("simulator: {0}")]
    Sim(#[from] traffic::SimError),
    /// Invalid experiment configuration.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// Filesystem error.
    #[error("i/o error on {path}: {source}")]
    Io {
        /// File or directory involved.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// JSON serialisation failed.
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
    /// An MCAP recording could not be written or read.
    #[error(transparent)]
    Recording(#[from] recording::RecordingError),
    /// The live view could not start.
    #[error(transparent)]
    Live(#[from] live_view::LiveError),
    /// CSV writing failed.
    #[error("csv: {0}")]
    Csv(#[from] csv::Error),
    /// Plot rendering failed.
    #[error("plot {path}: {message}")]
    Plot {
        /// Output file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

impl SimClientError {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl AsRef<std::path::Path>, source: std::io::Error) -> Self {
        SimClientError::Io {
            path: path.as_ref().display().to_string(),
            source,
        }
    }
}

/// Result alias of the library.
pub type Result<T, E = SimClientError> = std::result::Result<T, E>;
