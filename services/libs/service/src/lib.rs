//! The planner service, without its command line (`planner serve` wires it up).
//!
//! * [`Service`]: the transport-free core. A front end hands it each request with a reply
//!   callback ([`Service::submit`], [`Service::handle_bytes`], [`Service::refuse`]); the
//!   callback is called exactly once, by a worker, by the deadline watchdog, or at once for
//!   a request that fails a check or finds the service overloaded. Requests wait in a fair
//!   queue (round-robin across vehicles, a share and a rate per vehicle).
//! * Front ends: [`iceoryx2_front`] (shared memory, this machine), [`zenoh_front`] (queries
//!   across machines, the statistics publication, the instance's liveliness) and
//!   [`ros2_front`] (a ROS 2 node: a service, the decisions and RViz markers on topics).
//! * [`config_file`]: the planner's TOML configuration with the service's `[service]` table.
//!
//! The request life cycle, the threads and the flags are in docs/service.md.

pub mod config_file;
mod fair_queue;
pub mod iceoryx2_front;
pub mod ros2_front;
mod service;
pub mod zenoh_front;

pub use fair_queue::RateLimit;
pub use service::{
    Reply, Service, ServiceConfig, ServiceError, Stats, StatsSnapshot, QUEUE_PER_VEHICLE, QUEUE_PER_WORKER,
    WATCHDOG_RT_PRIORITY, WORKER_NICE,
};
