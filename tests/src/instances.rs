//! Several planner instances behind one `hmdp-router` (scale-out and failover tests).

use std::path::Path;
use std::time::{Duration, Instant};

use transport::zenoh::{ZenohChannel, ZenohTarget};

use crate::{free_port, Process};

/// The instance ids the tests start.
pub const INSTANCES: [&str; 2] = ["alpha", "beta"];

/// How long a debug build on a shared machine may take to start answering.
const STARTUP: Duration = Duration::from_secs(60);

/// A router and one planner per id of [`INSTANCES`], connected to it.
pub struct RoutedPlanners {
    pub router: Process,
    /// The router's endpoint, e.g. `tcp/127.0.0.1:41234`.
    pub endpoint: String,
    /// In the order of [`INSTANCES`].
    pub planners: Vec<Process>,
}

impl RoutedPlanners {
    pub fn start(tag: &str) -> Self {
        let endpoint = format!("tcp/127.0.0.1:{}", free_port());
        let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/zenoh/router.json5");
        let router = Process::start(
            "hmdp-router",
            &["--config", config.to_str().unwrap(), "--listen", &endpoint],
            &format!("{tag}-router"),
        );
        let planners = INSTANCES
            .iter()
            .map(|id| {
                let args = [
                    "serve",
                    "--zenoh-connect",
                    &endpoint,
                    "--workers",
                    "1",
                    "--instance-id",
                    id,
                ];
                Process::start("planner", &args, &format!("{tag}-{id}"))
            })
            .collect();
        Self {
            router,
            endpoint,
            planners,
        }
    }

    /// Every process's log so far, labelled.
    pub fn logs(&self) -> String {
        let mut all = format!("router:\n{}", self.router.log());
        for (id, p) in INSTANCES.iter().zip(&self.planners) {
            all += &format!("\n{id}:\n{}", p.log());
        }
        all
    }

    /// Stops every planner (SIGTERM, a clean exit asserted); each one's final statistics.
    pub fn final_statistics(&mut self) -> Vec<serde_json::Value> {
        let logs = self.logs();
        self.planners
            .iter_mut()
            .map(|p| {
                assert!(
                    p.terminate(Duration::from_secs(10)).is_some_and(|s| s.success()),
                    "{logs}"
                );
                p.final_statistics()
            })
            .collect()
    }

    /// A vehicle's channel (answers awaited for `deadline`), once it gets an answer and sees
    /// every instance's liveliness token; panics with the logs if that does not happen.
    pub fn vehicle(&self, deadline: Duration) -> ZenohChannel {
        let target = ZenohTarget {
            endpoint: Some(self.endpoint.clone()),
            ..Default::default()
        };
        let channel = ZenohChannel::connect(&target, STARTUP, deadline)
            .unwrap_or_else(|e| panic!("no planner answers: {e}\n{}", self.logs()));
        let since = Instant::now();
        while channel.instances() != INSTANCES {
            assert!(
                since.elapsed() < STARTUP,
                "instances seen: {:?}\n{}",
                channel.instances(),
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        channel
    }
}
