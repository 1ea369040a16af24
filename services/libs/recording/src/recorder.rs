//! The service's recorder: a writer thread fed by a bounded channel.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use protocol::{PlanRequest, PlanResponse};

use crate::error::{RecordingError, Result};
use crate::observer::{Observers, PlanObserver, WallClock};
use crate::schema;
use crate::sink::{ChannelSpec, McapSink, Rotation};
use crate::{PLANNER_SCENE_TOPIC, REQUEST_TOPIC, RESPONSE_TOPIC, STATS_TOPIC};

/// The channels of a planner recording, in the order of [`Kind`].
pub const PLANNER_CHANNELS: [ChannelSpec; 3] = [
    ChannelSpec {
        topic: REQUEST_TOPIC,
        schema_name: "hmdp.PlanRequest",
        schema: schema::plan_request,
    },
    ChannelSpec {
        topic: RESPONSE_TOPIC,
        schema_name: "hmdp.PlanResponse",
        schema: schema::plan_response,
    },
    ChannelSpec {
        topic: STATS_TOPIC,
        schema_name: "hmdp.PlannerStats",
        schema: schema::planner_stats,
    },
];

/// The channel of the planner's scene of each answer (the live view's; not recorded).
pub const PLANNER_SCENE_CHANNEL: ChannelSpec = ChannelSpec {
    topic: PLANNER_SCENE_TOPIC,
    schema_name: crate::scene::SCENE_SCHEMA_NAME,
    schema: crate::scene::scene_update_schema,
};

/// Where and how to record.
#[derive(Debug, Clone)]
pub struct RecorderOptions {
    /// The (first) file.
    pub path: PathBuf,
    pub rotation: Rotation,
    /// Records that may wait for the writer thread; beyond that they are dropped and counted.
    pub capacity: usize,
}

impl RecorderOptions {
    /// Recording to `path`, no rotation, room for 8192 waiting records (20 s of 32 vehicles
    /// at 12.5 Hz, requests and answers).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            rotation: Rotation::default(),
            capacity: 8192,
        }
    }
}

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct RecordingSummary {
    pub files: Vec<PathBuf>,
    pub messages: u64,
    /// Records dropped because the writer thread was behind (or had failed).
    pub dropped: u64,
}

enum Record {
    Request(u64, Arc<PlanRequest>),
    Response(u64, Arc<PlanResponse>),
    Stats(u64, Vec<u8>),
    Stop,
}

/// The writer thread: it returns the files written and the message count.
type WriterThread = JoinHandle<Result<(Vec<PathBuf>, u64)>>;

struct Shared {
    dropped: AtomicU64,
    thread: Mutex<Option<WriterThread>>,
    /// Log times are wall-clock nanoseconds.
    clock: WallClock,
}

/// A handle to the recording (cheap to clone). Every method returns at once.
#[derive(Clone)]
pub struct PlanRecorder {
    tx: SyncSender<Record>,
    shared: Arc<Shared>,
}

impl std::fmt::Debug for PlanRecorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlanRecorder")
            .field("dropped", &self.dropped())
            .finish_non_exhaustive()
    }
}

impl PlanRecorder {
    /// Creates the file and starts the writer thread.
    pub fn start(options: &RecorderOptions) -> Result<Self> {
        let sink = McapSink::create(&options.path, PLANNER_CHANNELS.to_vec(), options.rotation)?;
        let (tx, rx) = mpsc::sync_channel(options.capacity.max(1));
        let thread = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || write_loop(sink, &rx))
            .map_err(|e| RecordingError::io(&options.path, e))?;
        Ok(Self {
            tx,
            shared: Arc::new(Shared {
                dropped: AtomicU64::new(0),
                thread: Mutex::new(Some(thread)),
                clock: WallClock::now(),
            }),
        })
    }

    /// Wall-clock nanoseconds at `t`.
    pub fn log_time(&self, t: Instant) -> u64 {
        self.shared.clock.ns(t)
    }

    fn send(&self, record: Record) {
        match self.tx.try_send(record) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Records a request received at `arrival`.
    pub fn request(&self, request: &PlanRequest, arrival: Instant) {
        self.send(Record::Request(self.log_time(arrival), Arc::new(request.clone())));
    }

    /// Records an answer given at `at`.
    pub fn response(&self, response: PlanResponse, at: Instant) {
        self.send(Record::Response(self.log_time(at), Arc::new(response)));
    }

    /// Records a statistics document.
    pub fn stats<T: serde::Serialize>(&self, doc: &T) {
        match crate::json::to_vec(doc) {
            Ok(data) => self.send(Record::Stats(self.log_time(Instant::now()), data)),
            Err(_) => {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Records `request` now and returns `reply` wrapped so that it records the answer after
    /// passing it on (the copy costs a memcpy; encoding happens on the writer thread): the
    /// recorder as the only [`PlanObserver`] of [`Observers::wrap_reply`].
    pub fn wrap_reply<F>(&self, request: &PlanRequest, arrival: Instant, reply: F) -> impl FnOnce(PlanResponse) + Send
    where
        F: FnOnce(PlanResponse) + Send + 'static,
    {
        Observers::new(vec![Arc::new(self.clone())]).wrap_reply(request, arrival, reply)
    }

    /// Records dropped so far.
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    /// Writes what is queued, closes the file and stops the thread. Records sent afterwards
    /// (by another handle) are dropped. A second call returns an empty summary.
    pub fn finish(&self) -> Result<RecordingSummary> {
        let thread = self.shared.thread.lock().unwrap_or_else(|e| e.into_inner()).take();
        let Some(thread) = thread else {
            return Ok(RecordingSummary {
                files: Vec::new(),
                messages: 0,
                dropped: self.dropped(),
            });
        };
        // Blocking here is fine: the service has stopped answering.
        let _ = self.tx.send(Record::Stop);
        let (files, messages) = thread.join().map_err(|_| RecordingError::WriterGone)??;
        Ok(RecordingSummary {
            files,
            messages,
            dropped: self.dropped(),
        })
    }
}

/// The service's recorder: requests and answers shared, not copied again.
impl PlanObserver for PlanRecorder {
    fn name(&self) -> &'static str {
        "recorder"
    }

    fn request(&self, request: &Arc<PlanRequest>, arrival: Instant) {
        self.send(Record::Request(self.log_time(arrival), Arc::clone(request)));
    }

    fn response(&self, _request: &Arc<PlanRequest>, response: &Arc<PlanResponse>, at: Instant) {
        self.send(Record::Response(self.log_time(at), Arc::clone(response)));
    }

    fn stats(&self, json: &[u8], at: Instant) {
        self.send(Record::Stats(self.log_time(at), json.to_vec()));
    }

    fn dropped(&self) -> u64 {
        PlanRecorder::dropped(self)
    }
}

fn write_loop(mut sink: McapSink, rx: &Receiver<Record>) -> Result<(Vec<PathBuf>, u64)> {
    let mut failed = false;
    while let Ok(record) = rx.recv() {
        let result = match record {
            Record::Request(at, request) => sink.write_json(0, at, &*request),
            Record::Response(at, response) => sink.write_json(1, at, &*response),
            Record::Stats(at, data) => sink.write(2, at, at, &data),
            Record::Stop => break,
        };
        if let Err(e) = result {
            // Keep draining so that senders never wait; the file ends at the failure.
            if !failed {
                tracing::error!(error = %e, "recording failed; further records are dropped");
            }
            failed = true;
        }
    }
    let messages = sink.messages();
    Ok((sink.finish()?, messages))
}
