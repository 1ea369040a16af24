//! What watches the service: the recording (`--record`) and the live view (`--foxglove`),
//! both [`PlanObserver`]s on the service's answer path, and the statistics they get every
//! second.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use live_view::{LiveOptions, PlannerView};
use planner_service::{Stats, StatsSnapshot};
use recording::{Observers, PlanObserver, PlanRecorder, RecorderOptions, Rotation};

use super::ServeArgs;

/// The observers of one `planner serve`.
pub struct Watching {
    recorder: Option<PlanRecorder>,
    live: Option<Arc<PlannerView>>,
    observers: Observers,
}

/// The thread that hands the statistics to the observers once a second.
pub struct StatsThread {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Watching {
    /// Starts the recording and the live view the command line asks for.
    pub fn start(args: &ServeArgs) -> Result<Self> {
        let recorder = match &args.record {
            Some(path) => {
                let mut options = RecorderOptions::new(path);
                options.rotation = Rotation {
                    max_bytes: args.record_rotate_mib.map(|m| m.saturating_mul(1 << 20)),
                    max_duration: args.record_rotate_every,
                };
                tracing::info!(file = %path.display(), "recording");
                Some(PlanRecorder::start(&options).with_context(|| format!("recording to {}", path.display()))?)
            }
            None => None,
        };
        let live = match args.foxglove {
            Some(addr) => {
                let view = PlannerView::start(&LiveOptions::new(addr, "hmdp planner"))
                    .with_context(|| format!("--foxglove {addr}"))?;
                Some(Arc::new(view))
            }
            None => None,
        };
        let mut observers: Vec<Arc<dyn PlanObserver>> = Vec::new();
        if let Some(r) = &recorder {
            observers.push(Arc::new(r.clone()));
        }
        if let Some(v) = &live {
            observers.push(Arc::clone(v) as Arc<dyn PlanObserver>);
        }
        Ok(Self {
            recorder,
            live,
            observers: Observers::new(observers),
        })
    }

    /// For the service's configuration.
    pub fn observers(&self) -> Observers {
        self.observers.clone()
    }

    /// Hands the statistics document to the observers every second, as the Zenoh front
    /// publishes it, and warns when one of them dropped messages; `None` without observers.
    pub fn publish_stats(&self, stats: Arc<Stats>) -> Option<StatsThread> {
        if self.observers.is_empty() {
            return None;
        }
        let observers = self.observers.clone();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut dropped: Vec<u64> = vec![0; observers.iter().count()];
            let mut next = Instant::now();
            while !stopped.load(Ordering::Relaxed) {
                next += Duration::from_secs(1);
                while Instant::now() < next && !stopped.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(50));
                }
                observers.stats(&stats.snapshot());
                for (o, seen) in observers.iter().zip(dropped.iter_mut()) {
                    if o.dropped() > *seen {
                        *seen = o.dropped();
                        tracing::warn!(dropped = *seen, "the {} is behind: messages dropped", o.name());
                    }
                }
            }
        });
        Some(StatsThread { stop, thread })
    }

    /// After the service stopped: the final statistics to every observer, the recording
    /// completed, the live view stopped.
    pub fn finish(self, stats_thread: Option<StatsThread>, snapshot: &StatsSnapshot) -> Result<()> {
        if let Some(t) = stats_thread {
            t.stop.store(true, Ordering::Relaxed);
            let _ = t.thread.join();
        }
        self.observers.stats(snapshot);
        if let Some(recorder) = self.recorder {
            let summary = recorder.finish()?;
            tracing::info!(
                files = ?summary.files,
                messages = summary.messages,
                dropped = summary.dropped,
                "recording finished"
            );
        }
        drop(self.observers);
        if let Some(live) = self.live {
            // The last handle.
            let counters = match Arc::try_unwrap(live) {
                Ok(view) => view.finish(),
                Err(view) => view.server().counters(),
            };
            tracing::info!(
                published = counters.published,
                dropped = counters.dropped,
                "live view stopped"
            );
        }
        Ok(())
    }
}
