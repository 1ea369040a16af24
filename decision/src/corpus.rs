//! Seeded random situations for the agreement tests and the benchmark: the paper's 18
//! traffic classes (Table I), with the ego placed among the SVs so that many situations are
//! tight — lanes blocked, SVs closing in, corrective modes from memory — because those are
//! the ones that exercise the solver and the recovery layers.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::config::PlannerConfig;
use crate::types::{Action, CorrectiveEntry, EgoState, Maneuver, PlannerMemory, Road, Situation, SvObservation};

/// One traffic class of Table I.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrafficClass {
    /// Table I row id, 1..=18.
    pub id: u8,
    pub lanes: u8,
    pub svs: usize,
    pub speed_min_mps: f64,
    pub speed_max_mps: f64,
}

impl TrafficClass {
    pub fn is_highway(&self) -> bool {
        self.speed_min_mps >= 25.0
    }
}

/// The 18 classes of Table I in order: lanes {2, 3, 4} x speeds {[10, 20], [25, 40]} x
/// SVs {5, 8, 10}.
pub fn paper_classes() -> Vec<TrafficClass> {
    let mut out = Vec::with_capacity(18);
    let mut id = 1;
    for lanes in [2u8, 3, 4] {
        for (lo, hi) in [(10.0, 20.0), (25.0, 40.0)] {
            for svs in [5usize, 8, 10] {
                out.push(TrafficClass {
                    id,
                    lanes,
                    svs,
                    speed_min_mps: lo,
                    speed_max_mps: hi,
                });
                id += 1;
            }
        }
    }
    out
}

/// Deterministic generator of situations.
pub struct SituationGenerator {
    rng: ChaCha8Rng,
}

impl SituationGenerator {
    pub fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// A random situation of a class with exactly `class.svs` SVs.
    pub fn situation(&mut self, config: &PlannerConfig, class: &TrafficClass) -> Situation {
        let rng = &mut self.rng;
        let w = 4.0;
        let lanes = class.lanes;
        let road = Road {
            lanes,
            lane_width_m: w,
            speed_limit_mps: class.speed_max_mps + 5.0,
        };
        let centre = |lane: u8| f64::from(lanes - lane) * w;
        let (lo, hi) = (class.speed_min_mps, class.speed_max_mps);
        let ego_lane = rng.random_range(1..=lanes);
        let mut ego_target = ego_lane;
        let mut ego_y = centre(ego_lane);
        if lanes > 1 && rng.random_bool(0.2) {
            // A lane change under way: target a neighbour, body part way across.
            let dir: i8 = if ego_lane == 1 {
                1
            } else if ego_lane == lanes {
                -1
            } else if rng.random_bool(0.5) {
                1
            } else {
                -1
            };
            ego_target = (i16::from(ego_lane) + i16::from(dir)) as u8;
            let progress = rng.random_range(0.1..0.9);
            ego_y = centre(ego_lane) + (centre(ego_target) - centre(ego_lane)) * progress;
        }
        let ego = EgoState {
            x_m: 1000.0,
            y_m: ego_y,
            v_mps: rng.random_range(lo..=hi),
            desired_speed_mps: hi,
            maneuver: Maneuver {
                lane: ego_target,
                beta: rng.random_range(-1..=1),
            },
        };
        let length = config.vehicle.length_m;
        let ego_lanes = [ego_lane, ego_target];
        let mut placed: Vec<(f64, u8)> = vec![(ego.x_m, ego_lane), (ego.x_m, ego_target)];
        let mut svs = Vec::with_capacity(class.svs);
        let mut id = 1u32;
        while svs.len() < class.svs {
            let lane = rng.random_range(1..=lanes);
            // Mostly inside the perception window, a few beyond it.
            let x = ego.x_m + rng.random_range(-100.0..180.0);
            let v = rng.random_range(lo..=hi);
            if placed
                .iter()
                .any(|&(px, pl)| pl == lane && (px - x).abs() < length + 1.0)
            {
                continue;
            }
            let mut y = centre(lane);
            let mut sv_lanes = vec![lane];
            if lanes > 1 && rng.random_bool(0.1) {
                let other = if lane == lanes { lane - 1 } else { lane + 1 };
                y += (centre(other) - y) * rng.random_range(0.1..0.5);
                sv_lanes.push(other);
            }
            // Traffic keeps roughly its IDM spacing to the ego: mostly 1.0-2.0 times the IDM
            // distance, sometimes much closer (the situations the recovery layers are for).
            if sv_lanes.iter().any(|l| ego_lanes.contains(l)) && !rng.random_bool(0.04) {
                let gap = (x - ego.x_m).abs() - length;
                let d_idm = if x >= ego.x_m {
                    crate::idm::idm_distance(&config.idm, ego.v_mps, v)
                } else {
                    crate::idm::idm_distance(&config.idm, v, ego.v_mps)
                };
                if gap < rng.random_range(1.0..2.0) * d_idm {
                    continue;
                }
            }
            placed.push((x, lane));
            let a = [-1.2, -0.1, 0.0, 0.0, 0.8][rng.random_range(0..5)];
            svs.push(SvObservation::new(id, x, y, v, a));
            id += rng.random_range(1..4);
        }
        // Corrective memory for some SVs ahead in the ego's lane. In closed loop the trigger
        // fires as the predicted gap first dips below it, so the frozen trigger sits at most a
        // little above the current gap, and often well below it (the ego has backed off).
        let mut corrective = Vec::new();
        for sv in &svs {
            let gap = sv.x_m - ego.x_m - length;
            let same_lane = (sv.y_m - ego_y).abs() < w;
            if gap > 0.0 && same_lane && rng.random_bool(0.5) {
                let trigger = gap + rng.random_range(-15.0..2.0);
                corrective.push(CorrectiveEntry {
                    sv_id: sv.id,
                    trigger_m: trigger,
                    release_m: trigger + rng.random_range(2.4..8.8),
                });
            }
        }
        let previous_plan = if rng.random_bool(0.3) {
            (0..config.timing.horizon)
                .map(|_| {
                    [
                        Action::KEEP,
                        Action {
                            lateral: 0,
                            longitudinal: 1,
                        },
                        Action {
                            lateral: -1,
                            longitudinal: 0,
                        },
                    ][rng.random_range(0..3)]
                })
                .collect()
        } else {
            Vec::new()
        };
        Situation {
            road,
            ego,
            svs,
            memory: PlannerMemory {
                corrective,
                previous_plan,
            },
        }
    }
}

/// Judge the MILP's decision against the oracle's on one situation: same layer, same
/// corrective set; for a solved layer the MILP's plan must be feasible for the exact
/// evaluation and cost the same within `1e-6`; for the fallback, the same maneuver.
pub fn agree(
    config: &PlannerConfig,
    situation: &Situation,
    milp: &crate::Decision,
    oracle: &crate::Decision,
) -> Result<(), String> {
    use crate::evaluate::{evaluate, Mode};
    use crate::Layer;
    if milp.layer != oracle.layer {
        return Err(format!("layer {:?} vs oracle {:?}", milp.layer, oracle.layer));
    }
    if milp.memory.corrective != oracle.memory.corrective {
        return Err("corrective sets differ".into());
    }
    let mode = match milp.layer {
        Layer::Fallback => {
            return if milp.next_maneuver == oracle.next_maneuver {
                Ok(())
            } else {
                Err(format!(
                    "fallback {:?} vs oracle {:?}",
                    milp.next_maneuver, oracle.next_maneuver
                ))
            };
        }
        Layer::Nominal => Mode::Nominal,
        Layer::GlobalRelaxation => Mode::Relaxed,
    };
    let problem = crate::problem::prepare(config, situation).problem;
    let actions: Vec<Action> = milp.plan.iter().map(|p| p.action).collect();
    let exact = evaluate(&problem, &actions, mode).ok_or_else(|| {
        let other = evaluate(&problem, &actions, Mode::Relaxed).map(|e| e.cost);
        let accel: Vec<f64> = milp.plan.iter().map(|p| p.v_mps).collect();
        format!(
            "MILP plan infeasible for the oracle in {mode:?} (relaxed: {other:?}); speeds {accel:?}; oracle cost {:?}",
            oracle.stats.cost
        )
    })?;
    let (a, b) = (exact.cost, oracle.stats.cost.ok_or("oracle has no cost")?);
    if (a - b).abs() > 1e-6 {
        return Err(format!("cost {a} vs oracle {b}"));
    }
    Ok(())
}
