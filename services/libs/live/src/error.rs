//! The live view's errors.

use std::net::SocketAddr;

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The WebSocket server could not listen (the address is in use, not this host's).
    #[error("live view: cannot listen on {addr}")]
    Bind {
        addr: SocketAddr,
        #[source]
        source: foxglove::FoxgloveError,
    },
    /// A channel could not be declared.
    #[error("live view: cannot declare channel `{topic}`")]
    Channel {
        topic: String,
        #[source]
        source: foxglove::FoxgloveError,
    },
    /// A channel's JSON Schema could not be encoded.
    #[error("live view: the schema of `{topic}`")]
    Schema {
        topic: String,
        #[source]
        source: serde_json::Error,
    },
    /// Two channels with one topic.
    #[error("live view: two channels named `{0}`")]
    DuplicateTopic(String),
    /// A thread or the server's runtime could not be started.
    #[error("live view: starting its threads")]
    Spawn(#[source] std::io::Error),
    /// The server's thread ended while starting.
    #[error("live view: the server thread stopped while starting")]
    ServerGone,
}
