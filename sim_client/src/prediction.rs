//! The planner's SV predictions at a decision instant, recomputed from the situation it was
//! sent (the decision does not carry them). Same code path as the planner: validation, then
//! the problem preparation with its perception window and scenario trees. Pure.

use decision::{InputError, PlannerConfig, Situation, ValidSituation};

/// One step of a predicted branch: the SV moves from `x_from_m` to `x_to_m` in `lane` with
/// longitudinal mode `beta`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictedStep {
    /// Mean position at the start of the step (m).
    pub x_from_m: f64,
    /// Mean position at its end (m).
    pub x_to_m: f64,
    /// Target lane of the step's maneuver.
    pub lane: u8,
    /// Longitudinal mode of the step's maneuver.
    pub beta: i8,
}

/// One kept branch of an SV's scenario tree.
#[derive(Debug, Clone, PartialEq)]
pub struct PredictedBranch {
    /// Probability after pruning and renormalisation.
    pub probability: f64,
    /// Its steps over the horizon.
    pub steps: Vec<PredictedStep>,
}

/// Every kept branch of one SV.
#[derive(Debug, Clone, PartialEq)]
pub struct SvPrediction {
    /// SV id.
    pub sv_id: u32,
    /// Kept branches, most probable first.
    pub branches: Vec<PredictedBranch>,
}

/// The branches the planner kept for every SV in its perception window.
pub fn sv_predictions(config: &PlannerConfig, situation: &Situation) -> Result<Vec<SvPrediction>, InputError> {
    let valid = ValidSituation::new(config, situation)?;
    let situation = valid.get();
    let prepared = decision::prepare(config, situation);
    Ok(prepared
        .problem
        .svs
        .iter()
        .map(|sv| {
            let x0 = situation.svs.iter().find(|o| o.id == sv.id).map_or(0.0, |o| o.x_m);
            SvPrediction {
                sv_id: sv.id,
                branches: sv
                    .branches
                    .iter()
                    .map(|b| PredictedBranch {
                        probability: b.probability,
                        steps: b
                            .x
                            .iter()
                            .zip(&b.maneuvers)
                            .scan(x0, |from, (&x, m)| {
                                let step = PredictedStep {
                                    x_from_m: *from,
                                    x_to_m: x,
                                    lane: m.lane,
                                    beta: m.beta,
                                };
                                *from = x;
                                Some(step)
                            })
                            .collect(),
                    })
                    .collect(),
            }
        })
        .collect())
}
