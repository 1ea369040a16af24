//! [`LiveServer`]: the `foxglove` crate's WebSocket server on a thread of its own, fed by a
//! publisher thread through a bounded channel.
//!
//! Threads: `live-view-ws` runs a single-threaded tokio runtime with the server (accepting,
//! one task per client writing its queue to the socket); `live-view-publish` takes messages
//! from the bounded channel, encodes them and logs them on their foxglove channel, which copies
//! them into each subscribed client's queue (`foxglove`'s, [`LiveOptions::client_backlog`]
//! places: a client that does not read fast enough loses its oldest messages, the server never
//! waits for it).

use std::collections::HashMap;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Context, PartialMetadata, RawChannel, Schema};
use recording::ChannelSpec;

use crate::error::LiveError;

/// Foxglove's default port.
pub const DEFAULT_PORT: u16 = 8765;
/// Foxglove's default address: `127.0.0.1:8765` (this machine only).
pub const DEFAULT_ADDR: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), DEFAULT_PORT);

/// How long a stopping server lets its clients' connections close.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(1);

/// Where and how to serve.
#[derive(Debug, Clone)]
pub struct LiveOptions {
    /// Address to listen on; port 0: a free port ([`LiveServer::local_addr`] tells which).
    pub addr: SocketAddr,
    /// The server's name, shown by Foxglove.
    pub name: String,
    /// Messages that may wait for the publisher thread; beyond that they are dropped and
    /// counted ([`LiveCounters::dropped`]).
    pub capacity: usize,
    /// Messages that may wait for one client's socket (the `foxglove` crate's backlog); beyond
    /// that the client's oldest are dropped.
    pub client_backlog: usize,
}

impl LiveOptions {
    /// Serving on `addr` as `name`, 1024 places in the channel and per client.
    pub fn new(addr: SocketAddr, name: impl Into<String>) -> Self {
        Self {
            addr,
            name: name.into(),
            capacity: 1024,
            client_backlog: 1024,
        }
    }
}

/// A channel of a [`LiveServer`], by its place in the list it was started with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LiveChannel(usize);

/// What the publisher did so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LiveCounters {
    /// Messages handed to the server (for at least one subscribed client).
    pub published: u64,
    /// Messages dropped because the publisher thread was behind.
    pub dropped: u64,
    /// Messages whose encoding failed (logged).
    pub failed: u64,
}

/// A message's bytes, or how to make them on the publisher thread.
enum Payload {
    Bytes(Vec<u8>),
    Build(Box<dyn FnOnce() -> serde_json::Result<Vec<u8>> + Send>),
}

enum Job {
    Message {
        channel: usize,
        log_time_ns: u64,
        payload: Payload,
    },
    /// Answered when everything queued before it is published.
    Flush(mpsc::SyncSender<()>),
}

/// Subscriptions per topic and connected clients, kept by the server's listener.
#[derive(Default)]
struct Watchers {
    subscribed: Mutex<HashMap<String, usize>>,
    changed: Condvar,
    clients: AtomicUsize,
}

impl Watchers {
    fn count(&self, topic: &str, change: impl FnOnce(&mut usize)) {
        let mut subscribed = self.subscribed.lock().unwrap_or_else(|e| e.into_inner());
        change(subscribed.entry(topic.to_owned()).or_default());
        self.changed.notify_all();
    }
}

/// Called by the server on its client tasks; counts only (must not block).
struct Listener(Arc<Watchers>);

impl ServerListener for Listener {
    fn on_subscribe(&self, _client: Client, channel: ChannelView) {
        self.0.count(channel.topic(), |n| *n += 1);
    }

    fn on_unsubscribe(&self, _client: Client, channel: ChannelView) {
        self.0.count(channel.topic(), |n| *n = n.saturating_sub(1));
    }

    fn on_client_connect(&self) {
        self.0.clients.fetch_add(1, Ordering::Relaxed);
    }

    fn on_client_disconnect(&self) {
        self.0.clients.fetch_sub(1, Ordering::Relaxed);
    }
}

struct Shared {
    channels: Vec<Arc<RawChannel>>,
    watchers: Arc<Watchers>,
    published: AtomicU64,
    dropped: AtomicU64,
    failed: AtomicU64,
}

/// A running live view. Every `publish` method returns at once; dropping it publishes what is
/// still queued, then stops the server (clients are disconnected) and its threads.
pub struct LiveServer {
    shared: Arc<Shared>,
    addr: SocketAddr,
    tx: Option<SyncSender<Job>>,
    publisher: Option<JoinHandle<()>>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    server: Option<JoinHandle<()>>,
    /// The channels' context; the server and the channels hold it weakly.
    _context: Arc<Context>,
}

impl std::fmt::Debug for LiveServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveServer")
            .field("addr", &self.addr)
            .field("counters", &self.counters())
            .finish_non_exhaustive()
    }
}

/// Declares `specs` as JSON channels with their JSON Schemas in `context`.
fn declare(context: &Arc<Context>, specs: &[ChannelSpec]) -> Result<Vec<Arc<RawChannel>>, LiveError> {
    let mut channels: Vec<Arc<RawChannel>> = Vec::with_capacity(specs.len());
    for spec in specs {
        if channels.iter().any(|c| c.topic() == spec.topic) {
            return Err(LiveError::DuplicateTopic(spec.topic.to_owned()));
        }
        let schema = serde_json::to_vec(&(spec.schema)()).map_err(|source| LiveError::Schema {
            topic: spec.topic.to_owned(),
            source,
        })?;
        let channel = context
            .channel_builder(spec.topic)
            .message_encoding("json")
            .schema(Schema::new(spec.schema_name, "jsonschema", schema))
            .build_raw()
            .map_err(|source| LiveError::Channel {
                topic: spec.topic.to_owned(),
                source,
            })?;
        channels.push(channel);
    }
    Ok(channels)
}

/// The server's thread: it starts the server, reports where it listens, and stops it when
/// `stop` fires (or its sender is dropped).
fn spawn_server(
    context: &Arc<Context>,
    options: &LiveOptions,
    watchers: &Arc<Watchers>,
    stop: tokio::sync::oneshot::Receiver<()>,
) -> Result<(SocketAddr, JoinHandle<()>), LiveError> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(LiveError::Spawn)?;
    let addr = options.addr;
    // foxglove binds "{host}:{port}": an IPv6 host needs its brackets.
    let host = match addr.ip() {
        IpAddr::V4(ip) => ip.to_string(),
        IpAddr::V6(ip) => format!("[{ip}]"),
    };
    let server = context
        .websocket_server()
        .name(options.name.clone())
        .bind(host, addr.port())
        .message_backlog_size(options.client_backlog.max(1))
        .listener(Arc::new(Listener(Arc::clone(watchers))));
    let (ready_tx, ready_rx) = mpsc::channel::<Result<SocketAddr, LiveError>>();
    let thread = std::thread::Builder::new()
        .name("live-view-ws".into())
        .spawn(move || {
            runtime.block_on(async move {
                let handle = match server.start().await {
                    Ok(handle) => handle,
                    Err(source) => {
                        let _ = ready_tx.send(Err(LiveError::Bind { addr, source }));
                        return;
                    }
                };
                let _ = ready_tx.send(Ok(SocketAddr::new(addr.ip(), handle.port())));
                let _ = stop.await;
                let shutdown = handle.stop();
                let _ = tokio::time::timeout(SHUTDOWN_GRACE, shutdown.wait()).await;
            });
        })
        .map_err(LiveError::Spawn)?;
    match ready_rx.recv() {
        Ok(Ok(local)) => Ok((local, thread)),
        Ok(Err(e)) => {
            let _ = thread.join();
            Err(e)
        }
        Err(_) => {
            let _ = thread.join();
            Err(LiveError::ServerGone)
        }
    }
}

impl LiveServer {
    /// Declares `channels` (JSON messages, their JSON Schemas) and starts serving them on
    /// `options.addr`. Blocks until the server listens; call it outside an async context.
    pub fn start(options: &LiveOptions, channels: &[ChannelSpec]) -> Result<Self, LiveError> {
        let context = Context::new();
        let channels = declare(&context, channels)?;
        let watchers = Arc::new(Watchers::default());
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel();
        let (addr, server) = spawn_server(&context, options, &watchers, stop_rx)?;
        let shared = Arc::new(Shared {
            channels,
            watchers,
            published: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            failed: AtomicU64::new(0),
        });
        let (tx, rx) = mpsc::sync_channel(options.capacity.max(1));
        let publisher = {
            let shared = Arc::clone(&shared);
            std::thread::Builder::new()
                .name("live-view-publish".into())
                .spawn(move || publish_loop(&shared, &rx))
        };
        let publisher = match publisher {
            Ok(p) => p,
            Err(e) => {
                let _ = stop_tx.send(());
                let _ = server.join();
                return Err(LiveError::Spawn(e));
            }
        };
        tracing::info!(%addr, "live view: open ws://{addr} in Foxglove");
        Ok(Self {
            shared,
            addr,
            tx: Some(tx),
            publisher: Some(publisher),
            stop: Some(stop_tx),
            server: Some(server),
            _context: context,
        })
    }

    /// Where the server listens (with the port chosen when asked for port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The channel of `topic`.
    pub fn channel(&self, topic: &str) -> Option<LiveChannel> {
        self.shared
            .channels
            .iter()
            .position(|c| c.topic() == topic)
            .map(LiveChannel)
    }

    /// Whether a client subscribes to `channel` now (publishing to a channel nobody watches
    /// costs nothing: the message is not even queued).
    pub fn is_watched(&self, channel: LiveChannel) -> bool {
        self.shared.channels.get(channel.0).is_some_and(|c| c.has_sinks())
    }

    /// Publishes `data` (the message's JSON) on `channel` with log time `log_time_ns` (Unix
    /// nanoseconds).
    pub fn publish(&self, channel: LiveChannel, log_time_ns: u64, data: Vec<u8>) {
        if self.is_watched(channel) {
            self.send(channel, log_time_ns, Payload::Bytes(data));
        }
    }

    /// Publishes `value` encoded as recording JSON (non-finite numbers as strings,
    /// `recording::json`) on the publisher thread.
    pub fn publish_json<T: serde::Serialize + Send + 'static>(&self, channel: LiveChannel, log_time_ns: u64, value: T) {
        self.publish_with(channel, log_time_ns, move || recording::json::to_vec(&value));
    }

    /// Publishes what `build` returns, called on the publisher thread (and only if a client
    /// still subscribes by then): what to move off the caller's thread, e.g. building a scene.
    pub fn publish_with<F>(&self, channel: LiveChannel, log_time_ns: u64, build: F)
    where
        F: FnOnce() -> serde_json::Result<Vec<u8>> + Send + 'static,
    {
        if self.is_watched(channel) {
            self.send(channel, log_time_ns, Payload::Build(Box::new(build)));
        }
    }

    fn send(&self, channel: LiveChannel, log_time_ns: u64, payload: Payload) {
        let job = Job::Message {
            channel: channel.0,
            log_time_ns,
            payload,
        };
        match self.tx.as_ref().map(|tx| tx.try_send(job)) {
            Some(Ok(())) => {}
            Some(Err(TrySendError::Full(_) | TrySendError::Disconnected(_))) | None => {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Waits until every message published before is handed to the server (then it is in
    /// each subscribed client's queue), at most `timeout` once the publisher gets to it;
    /// whether it did. Blocks while the channel is full: for the end of a run and tests, not
    /// for an answer path.
    pub fn flush(&self, timeout: Duration) -> bool {
        let Some(tx) = &self.tx else {
            return false;
        };
        let (done_tx, done) = mpsc::sync_channel(1);
        tx.send(Job::Flush(done_tx)).is_ok() && done.recv_timeout(timeout).is_ok()
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.shared.watchers.clients.load(Ordering::Relaxed)
    }

    /// Subscriptions to `topic` now.
    pub fn subscribers(&self, topic: &str) -> usize {
        let subscribed = self
            .shared
            .watchers
            .subscribed
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        subscribed.get(topic).copied().unwrap_or(0)
    }

    /// Waits until a client subscribes to `topic`, at most `timeout`; whether one does.
    pub fn wait_for_subscriber(&self, topic: &str, timeout: Duration) -> bool {
        let watchers = &self.shared.watchers;
        let deadline = Instant::now() + timeout;
        let mut subscribed = watchers.subscribed.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if subscribed.get(topic).is_some_and(|&n| n > 0) {
                return true;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            subscribed = watchers
                .changed
                .wait_timeout(subscribed, left)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    /// What the publisher did so far.
    pub fn counters(&self) -> LiveCounters {
        LiveCounters {
            published: self.shared.published.load(Ordering::Relaxed),
            dropped: self.shared.dropped.load(Ordering::Relaxed),
            failed: self.shared.failed.load(Ordering::Relaxed),
        }
    }
}

impl LiveServer {
    /// Publishes what is queued, stops the server and returns the final counters (what
    /// dropping it does, with the counters).
    pub fn finish(mut self) -> LiveCounters {
        self.shut_down();
        self.counters()
    }

    fn shut_down(&mut self) {
        // The publisher takes what is queued (at most `capacity` messages), then ends.
        self.tx = None;
        if let Some(publisher) = self.publisher.take() {
            let _ = publisher.join();
        }
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(server) = self.server.take() {
            let _ = server.join();
        }
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        self.shut_down();
    }
}

fn publish_loop(shared: &Shared, rx: &Receiver<Job>) {
    while let Ok(job) = rx.recv() {
        let (channel, log_time_ns, payload) = match job {
            Job::Message {
                channel,
                log_time_ns,
                payload,
            } => (channel, log_time_ns, payload),
            Job::Flush(done) => {
                let _ = done.try_send(());
                continue;
            }
        };
        let Some(channel) = shared.channels.get(channel) else {
            continue;
        };
        // The last subscriber may have left since the message was queued.
        if !channel.has_sinks() {
            continue;
        }
        let data = match payload {
            Payload::Bytes(data) => data,
            Payload::Build(build) => match build() {
                Ok(data) => data,
                Err(e) => {
                    if shared.failed.fetch_add(1, Ordering::Relaxed) == 0 {
                        tracing::warn!(topic = channel.topic(), error = %e, "live view: a message could not be encoded");
                    }
                    continue;
                }
            },
        };
        channel.log_with_meta(&data, PartialMetadata::with_log_time(log_time_ns));
        shared.published.fetch_add(1, Ordering::Relaxed);
    }
}
