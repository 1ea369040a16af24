//! MCAP recordings of the planner's traffic and of simulated trials.
//!
//! * [`McapSink`]: a synchronous MCAP writer with one channel per message kind (JSON messages,
//!   a JSON Schema per type, so that Foxglove shows them without plugins) and rotation by
//!   size or time.
//! * [`PlanRecorder`]: the service's recorder. Requests and answers go through a bounded
//!   channel to a writer thread; a full channel drops the record and counts it, so that
//!   recording never blocks the answer path.
//! * [`read_messages`] / [`read_exchanges`]: the reader used by `planner replay` and
//!   `sim_client replay`; a corrupt, truncated or foreign file is a [`RecordingError`].
//! * [`json`]: the messages' JSON, with non-finite floats as `"NaN"`, `"inf"`, `"-inf"` so
//!   that a recorded NaN reads back as NaN.
//! * [`PlanObserver`] / [`Observers`]: what watches the planner's traffic on the service's
//!   answer path (the recorder here, the live view in `live_view`).
//! * [`scene`]: the `foxglove.SceneUpdate` 3D scene of a simulator step or of a planner answer.
//!
//! Channels and schemas are listed in `docs/recording.md`.

mod error;
pub mod json;
mod observer;
mod reader;
mod recorder;
pub mod scene;
pub mod schema;
mod sink;

pub use error::{RecordingError, Result};
pub use observer::{Observers, PlanObserver, WallClock};
pub use reader::{read_exchanges, read_messages, Exchange, Exchanges, RecordedMessage};
pub use recorder::{PlanRecorder, RecorderOptions, RecordingSummary, PLANNER_CHANNELS, PLANNER_SCENE_CHANNEL};
pub use sink::{ChannelSpec, McapSink, Rotation};

/// Topic of the requests as the planner received them.
pub const REQUEST_TOPIC: &str = "/planner/request";
/// Topic of the planner's answers.
pub const RESPONSE_TOPIC: &str = "/planner/response";
/// Topic of the statistics documents (those published on `hmdp/planner/stats`).
pub const STATS_TOPIC: &str = "/planner/stats";
/// Topic of the planner's scene (`planner serve --foxglove`: a `foxglove.SceneUpdate` per
/// answer; not recorded).
pub const PLANNER_SCENE_TOPIC: &str = "/planner/scene";
