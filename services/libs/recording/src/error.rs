//! The recording's errors.

use std::path::PathBuf;

/// Result of this crate.
pub type Result<T, E = RecordingError> = std::result::Result<T, E>;

/// What can go wrong writing or reading a recording.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be created, written or read.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The MCAP layer failed (a corrupt or truncated file when reading).
    #[error("{}: not a valid MCAP file ({source})", path.display())]
    Mcap {
        path: PathBuf,
        #[source]
        source: mcap::McapError,
    },
    /// A message could not be encoded (a value JSON cannot hold).
    #[error("encoding a message for `{topic}`: {source}")]
    Encode {
        topic: String,
        #[source]
        source: serde_json::Error,
    },
    /// A message is not the JSON its channel promises.
    #[error("{}: message {index} on `{topic}` is not a valid {what}: {source}", path.display())]
    Decode {
        path: PathBuf,
        topic: String,
        index: usize,
        what: &'static str,
        #[source]
        source: serde_json::Error,
    },
    /// A channel the reader needs is absent (e.g. a foreign recording).
    #[error("{}: no channel `{topic}` (needed: {needed}; see docs/recording.md)", path.display())]
    MissingChannel {
        path: PathBuf,
        topic: String,
        needed: &'static str,
    },
    /// A channel carries another message encoding than JSON.
    #[error("{}: channel `{topic}` has message encoding `{encoding}`, expected `json`", path.display())]
    Encoding {
        path: PathBuf,
        topic: String,
        encoding: String,
    },
    /// The writer thread is gone (it failed earlier; its error was logged).
    #[error("the recording thread stopped")]
    WriterGone,
}

impl RecordingError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn mcap(path: impl Into<PathBuf>, source: mcap::McapError) -> Self {
        match source {
            mcap::McapError::Io(e) => Self::io(path, e),
            source => Self::Mcap {
                path: path.into(),
                source,
            },
        }
    }
}
