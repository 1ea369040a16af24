//! The planner service's library side: the solver benchmarks, the transport-free service core
//! (worker pool, fair queue, watchdog, statistics) and its front ends: iceoryx2 (same
//! machine, shared memory) and Zenoh (across machines); the replay of a recording
//! (`planner replay`).

pub mod bench;
pub mod fair_queue;
pub mod iceoryx2_front;
pub mod replay;
pub mod scaling;
pub mod service;
pub mod zenoh_front;
