//! The planner service's library side: the solver benchmark, the transport-free service core
//! (worker pool, watchdog, statistics) and its Zenoh front end.

pub mod bench;
pub mod service;
pub mod zenoh_front;
