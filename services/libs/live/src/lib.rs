//! The live view: a running planner or simulation watched in Foxglove while it runs, over
//! Foxglove's WebSocket protocol (the `foxglove` crate's server).
//!
//! * [`LiveServer`]: a WebSocket server on an address (default [`DEFAULT_ADDR`], Foxglove's
//!   default), with JSON channels declared up front from [`recording::ChannelSpec`]s (the
//!   recordings' topics and JSON Schemas) and a publisher that never blocks its caller: messages
//!   go through a bounded channel to a thread of its own, which encodes them and hands them to
//!   the server; a full channel drops the message and counts it. Nothing is encoded for a
//!   channel no client subscribes to. Dropping the server stops it.
//! * [`PlannerView`]: the planner's live view (`planner serve --foxglove`): a
//!   [`recording::PlanObserver`] publishing every request, answer and statistics document on
//!   the recording's topics, and a `foxglove.SceneUpdate` per answer.
//! * [`client`]: a small client of the protocol (`foxglove.sdk.v1`), written from the protocol's
//!   specification, for the tests and the `watch` example.
//!
//! How to watch and what it costs: docs/live-view.md.

pub mod client;
mod error;
mod planner;
mod server;

pub use error::LiveError;
pub use planner::PlannerView;
pub use server::{LiveChannel, LiveCounters, LiveOptions, LiveServer, DEFAULT_ADDR, DEFAULT_PORT};
