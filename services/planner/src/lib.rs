//! The planner service's library side: for now the solver benchmark.

pub mod bench;
