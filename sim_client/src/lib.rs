#![warn(missing_docs)]
//! Closed-loop simulation client: drives the `traffic` simulator with the HMDP-MPC planner
//! of the `decision` crate and reproduces the paper's experiments (section IV):
//! Case 1 (demonstration), Case 2 (hysteresis ablation) and Case 3 (randomized campaign).
//!
//! The planner is reached through [`link::PlannerLink`] only. The simulation loop
//! ([`episode`]), the metrics ([`metrics`]) and the experiment runners ([`cases`],
//! [`campaign`]) are pure; files are written by [`report`] and [`plot`]. [`load`] measures a
//! planner process under load (`sim_client load` / `soak`). [`record`] writes a trial to MCAP (with a Foxglove scene from
//! `recording::scene`), [`recorded`] runs the cases and campaign trials with it; [`live`]
//! shows a trial live in Foxglove; [`log_replay`] replays a recorded traffic log against the
//! planner.

pub mod campaign;
mod campaign_aggregate;
pub mod campaign_compare;
pub mod campaign_report;
pub mod cases;
pub mod connect;
pub mod diagnosis;
pub mod episode;
pub mod error;
mod inproc;
pub mod link;
pub mod live;
pub mod load;
pub mod log_replay;
pub mod metrics;
pub mod paper;
pub mod planner_process;
pub mod plot;
pub mod pool;
pub mod prediction;
pub mod presets;
pub mod record;
pub mod recorded;
pub mod report;
mod ros2_channel;
pub mod safety;

pub use connect::Transport;
pub use error::{Result, SimClientError};
pub use link::{InProcess, LinkError, LinkOptions, Planned, PlannerLink, RemoteLink};
pub use transport::zenoh::ZenohTarget;
pub use transport::PlanChannel;
