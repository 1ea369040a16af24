//! `planner replay`: re-decides every recorded request and compares with the recorded answer.
//!
//! Optimal solves are bit-for-bit repeatable, so "identical" means equal in every field of
//! the outcome (action, maneuver, set-point, plan, layer, memory); only the timings
//! (`solve_us`, `queue_us`) are ignored. An answer the watchdog gave is compared with the
//! deterministic fallback the watchdog would give again.

use decision::{Planner, PlannerConfig};
use protocol::{Layer, OutcomeRef, PlanResponse};
use recording::{Exchange, Exchanges};
use serde::Serialize;

/// How many differences a report lists.
pub const SHOWN_DIFFERENCES: usize = 10;

/// One request whose new answer differs from the recorded one.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Difference {
    /// Position of the request in the recording.
    pub index: usize,
    pub vehicle_id: u64,
    pub sequence: u64,
    /// The recorded and the new outcome, one line each.
    pub recorded: String,
    pub replayed: String,
    /// Names of the outcome's fields that differ.
    pub fields: Vec<&'static str>,
}

/// The result of a replay.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ReplayReport {
    /// Requests with a recorded answer, re-decided.
    pub compared: usize,
    /// Answers identical in every field.
    pub identical: usize,
    /// Answers that differ in any field.
    pub different: usize,
    /// Of these, answers from another layer (or a rejection where a decision was, or back).
    pub layer_different: usize,
    /// Recorded answers of the watchdog (and stale requests), compared with the fallback.
    pub watchdog_answers: usize,
    /// Requests without a recorded answer (not compared).
    pub unanswered: usize,
    /// Answers without a recorded request.
    pub unmatched_responses: usize,
    /// The first [`SHOWN_DIFFERENCES`] differences.
    pub first_differences: Vec<Difference>,
}

impl ReplayReport {
    /// Whether every compared answer was identical.
    pub fn all_identical(&self) -> bool {
        self.different == 0
    }
}

/// A one-line description of an answer.
pub fn describe(response: &PlanResponse) -> String {
    match response.outcome.get() {
        Ok(OutcomeRef::Decided(d)) => format!(
            "{} lane {} beta {} accel {:.4} plan [{}] corrective {}",
            d.layer()
                .map_or_else(|_| format!("layer#{}", d.layer_code()), |l| l.name().to_owned()),
            d.next_maneuver.lane,
            d.next_maneuver.beta,
            d.setpoint.accel_mps2,
            d.plan
                .iter()
                .map(|s| format!("{}{:+}", s.maneuver.lane, s.maneuver.beta))
                .collect::<Vec<_>>()
                .join(" "),
            d.memory.corrective.len()
        ),
        Ok(OutcomeRef::Rejected(r)) => format!(
            "rejected {} `{}`",
            r.reason()
                .map_or_else(|_| format!("#{}", r.reason_code()), |r| r.name().to_owned()),
            r.field()
        ),
        Err(e) => format!("invalid outcome: {e}"),
    }
}

/// The fields in which two answers' outcomes differ (empty: identical).
pub fn differing_fields(recorded: &PlanResponse, replayed: &PlanResponse) -> Vec<&'static str> {
    match (recorded.outcome.get(), replayed.outcome.get()) {
        (Ok(OutcomeRef::Decided(a)), Ok(OutcomeRef::Decided(b))) => {
            let mut fields = Vec::new();
            let checks: [(&'static str, bool); 6] = [
                ("layer", a.layer_code() == b.layer_code()),
                ("action", a.action == b.action),
                ("next_maneuver", a.next_maneuver == b.next_maneuver),
                // Bit for bit: `==` on f64 would call -0.0 and 0.0 equal.
                (
                    "setpoint",
                    a.setpoint.accel_mps2.to_bits() == b.setpoint.accel_mps2.to_bits()
                        && a.setpoint.target_speed_mps.to_bits() == b.setpoint.target_speed_mps.to_bits(),
                ),
                ("plan", a.plan == b.plan),
                ("memory", a.memory == b.memory),
            ];
            for (name, same) in checks {
                if !same {
                    fields.push(name);
                }
            }
            fields
        }
        (Ok(OutcomeRef::Rejected(a)), Ok(OutcomeRef::Rejected(b))) => {
            if a == b {
                Vec::new()
            } else {
                vec!["rejection"]
            }
        }
        _ => vec!["outcome"],
    }
}

/// The layer of a fallback the service (not the decision core) chose: the watchdog's or the
/// stale request's; these are replayed as the same fallback.
fn service_fallback(response: &PlanResponse) -> Option<Layer> {
    let layer = response.outcome.as_decided()?.layer().ok()?;
    matches!(layer, Layer::WatchdogFallback | Layer::StaleFallback).then_some(layer)
}

/// Re-decides every answered request of `exchanges` with one planner built from `config`.
pub fn replay(config: &PlannerConfig, exchanges: &Exchanges) -> Result<ReplayReport, decision::DecisionError> {
    let mut planner = Planner::new(config.clone())?;
    let mut report = ReplayReport {
        unmatched_responses: exchanges.unmatched_responses,
        ..ReplayReport::default()
    };
    for (index, Exchange { request, response, .. }) in exchanges.exchanges.iter().enumerate() {
        let Some(recorded) = response else {
            report.unanswered += 1;
            continue;
        };
        let replayed = match (request.clone().validate(config), service_fallback(recorded)) {
            (Err(invalid), _) => invalid.response(),
            (Ok(valid), Some(layer)) => {
                report.watchdog_answers += 1;
                protocol::fallback_answer(config, &valid, layer)
            }
            (Ok(valid), None) => protocol::answer(&mut planner, &valid),
        };
        report.compared += 1;
        let fields = differing_fields(recorded, &replayed);
        if fields.is_empty() {
            report.identical += 1;
            continue;
        }
        report.different += 1;
        if fields.contains(&"layer") || fields.contains(&"outcome") {
            report.layer_different += 1;
        }
        if report.first_differences.len() < SHOWN_DIFFERENCES {
            report.first_differences.push(Difference {
                index,
                vehicle_id: request.vehicle_id,
                sequence: request.sequence,
                recorded: describe(recorded),
                replayed: describe(&replayed),
                fields,
            });
        }
    }
    Ok(report)
}

/// Runs `planner replay`: the exit code is 1 when any answer differs.
pub fn run(files: &[std::path::PathBuf], config: Option<&std::path::Path>, json: bool) -> anyhow::Result<i32> {
    let config = planner_service::config_file::planner_config(config)?;
    let exchanges = recording::read_exchanges(files)?;
    let report = replay(&config, &exchanges)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "compared {}: identical {}, different {} (other layer {}); watchdog answers {}, unanswered {}, answers without request {}",
            report.compared,
            report.identical,
            report.different,
            report.layer_different,
            report.watchdog_answers,
            report.unanswered,
            report.unmatched_responses
        );
        for d in &report.first_differences {
            println!(
                "  #{} vehicle {} sequence {}: {} differ\n    recorded: {}\n    replayed: {}",
                d.index,
                d.vehicle_id,
                d.sequence,
                d.fields.join(", "),
                d.recorded,
                d.replayed
            );
        }
    }
    Ok(if report.all_identical() { 0 } else { 1 })
}
