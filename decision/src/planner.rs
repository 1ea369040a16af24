//! The entry point: Algorithm 1 of the paper, one decision per call.

use std::time::Instant;

use crate::config::{Backend, PlannerConfig};
use crate::enumeration;
use crate::error::DecisionError;
use crate::evaluate::{Evaluation, Mode};
use crate::fallback;
use crate::highs_solver::InterruptHandle;
use crate::milp::MilpBackend;
use crate::model::transition;
use crate::problem::{prepare, Problem};
use crate::types::{Action, Decision, Layer, Maneuver, PlanStep, SetPoint, Situation, SolveStats};
use crate::validate::ValidSituation;

/// A planner: configuration plus, for the MILP backend, one long-lived HiGHS instance.
/// It holds no decision state — the memory travels in `Situation` and `Decision` — but it
/// is tied to the thread that created it (HiGHS keeps per-thread state).
pub struct Planner {
    config: PlannerConfig,
    milp: Option<MilpBackend>,
}

struct LayerResult {
    evaluation: Option<Evaluation>,
    stopped: bool,
}

impl Planner {
    pub fn new(config: PlannerConfig) -> Result<Self, DecisionError> {
        config.validate()?;
        let milp = match config.solver.backend {
            Backend::Milp => Some(MilpBackend::new(&config.solver)?),
            Backend::Enumeration => None,
        };
        Ok(Self { config, milp })
    }

    pub fn config(&self) -> &PlannerConfig {
        &self.config
    }

    /// Handle to stop a running MILP solve from another thread (`None` for enumeration).
    pub fn interrupt_handle(&self) -> Option<InterruptHandle> {
        self.milp.as_ref().map(MilpBackend::interrupt_handle)
    }

    /// Id the next HiGHS solve will carry; a decision may run two (nominal, Layer A).
    pub fn next_solve_id(&self) -> Option<u64> {
        self.milp.as_ref().map(MilpBackend::next_solve_id)
    }

    /// Per-solve time limit of HiGHS, s.
    pub fn set_time_limit(&mut self, seconds: f64) -> Result<(), DecisionError> {
        if let Some(m) = self.milp.as_mut() {
            m.set_time_limit(seconds)?;
        }
        Ok(())
    }

    /// Decide: validate, then [`Planner::decide_valid`].
    pub fn decide(&mut self, situation: &Situation) -> Result<Decision, DecisionError> {
        let started = Instant::now();
        let valid = ValidSituation::new(&self.config, situation)?;
        self.decide_from(&valid, started)
    }

    /// Decide on a situation validated against this planner's configuration: refresh
    /// hysteresis, build the problem, solve the nominal MPC, then Layer A if it is
    /// infeasible, then Layer B if that is infeasible too. An SV ahead that needs braking
    /// beyond the MPC's range goes to Layer B at once (`SolveStats::emergency`). Fails only
    /// when the solver does.
    pub fn decide_valid(&mut self, situation: &ValidSituation) -> Result<Decision, DecisionError> {
        self.decide_from(situation, Instant::now())
    }

    /// [`Planner::decide_valid`], its total time counted from `started`.
    fn decide_from(&mut self, situation: &ValidSituation, started: Instant) -> Result<Decision, DecisionError> {
        let situation = situation.get();
        let prepared = prepare(&self.config, situation);
        let problem = &prepared.problem;
        let mut stats = SolveStats {
            svs_considered: problem.svs.len(),
            branches: problem.svs.iter().map(|c| c.branches.len()).sum(),
            corrective_svs: prepared.memory.corrective.len(),
            ..SolveStats::new(self.config.solver.backend)
        };
        // Layer B's choice, made once: it answers if both layers fail, and it decides now
        // whether an SV ahead only braking beyond the MPC's range keeps the ego behind. Then no
        // plan the MPC can make keeps it behind that SV, and the time a solve takes is braking
        // lost: Layer B brakes as hard as needed at once, in its lane as the paper's Layer B
        // does (docs/emergency-braking.md).
        let threat = fallback::choose(
            &self.config,
            situation,
            problem.ego.occupancy,
            &prepared.memory.corrective,
        );
        if fallback::needs_emergency_braking(&self.config, &problem.kin, &threat) {
            stats.emergency = true;
            let mut d = fallback_decision(
                &self.config,
                situation,
                problem,
                &threat,
                stats,
                prepared.memory.clone(),
            );
            d.stats.total_us = started.elapsed().as_micros() as u64;
            return Ok(d);
        }
        let warm = self.warm_candidates(situation);
        let solve_started = Instant::now();
        let mut layer = Layer::Nominal;
        let mut result = self.solve_layer(problem, Mode::Nominal, &warm, &mut stats)?;
        if result.evaluation.is_none() && !result.stopped {
            layer = Layer::GlobalRelaxation;
            result = self.solve_layer(problem, Mode::Relaxed, &warm, &mut stats)?;
        }
        stats.solve_us = solve_started.elapsed().as_micros() as u64;
        stats.interrupted = result.stopped;

        let mut memory = prepared.memory.clone();
        let decision = match result.evaluation {
            Some(e) => {
                stats.cost = Some(e.cost);
                memory.previous_plan = e.rollout.actions.clone();
                let plan: Vec<PlanStep> = (0..e.rollout.actions.len())
                    .map(|h| PlanStep {
                        action: e.rollout.actions[h],
                        maneuver: e.rollout.maneuvers[h],
                        x_m: e.rollout.x[h],
                        v_mps: e.rollout.v[h],
                        occupied_lanes: e.rollout.occupancy[h].0,
                    })
                    .collect();
                Decision {
                    action: plan[0].action,
                    next_maneuver: plan[0].maneuver,
                    setpoint: setpoint_of(problem, &plan[0]),
                    plan,
                    layer,
                    stats,
                    memory,
                }
            }
            None => fallback_decision(&self.config, situation, problem, &threat, stats, memory),
        };
        let mut decision = decision;
        decision.stats.total_us = started.elapsed().as_micros() as u64;
        Ok(decision)
    }

    /// The previous plan shifted by one step, and "keep everything".
    fn warm_candidates(&self, s: &Situation) -> Vec<Vec<Action>> {
        let h = self.config.timing.horizon;
        let mut out = vec![vec![Action::KEEP; h]];
        let prev = &s.memory.previous_plan;
        if prev.len() > 1 {
            let mut shifted: Vec<Action> = prev[1..].to_vec();
            shifted.resize(h, Action::KEEP);
            // Cruising, the shifted plan is "keep everything" again: one LP, not two.
            if shifted != out[0] {
                out.insert(0, shifted);
            }
        }
        out
    }

    fn solve_layer(
        &mut self,
        problem: &Problem,
        mode: Mode,
        warm: &[Vec<Action>],
        stats: &mut SolveStats,
    ) -> Result<LayerResult, DecisionError> {
        match self.milp.as_mut() {
            Some(milp) => {
                let out = milp.solve(problem, mode, if self.config.solver.warm_start { warm } else { &[] })?;
                stats.rows = out.rows;
                stats.columns = out.columns;
                stats.binaries = out.binaries;
                stats.nodes += out.nodes;
                stats.warm_start |= out.warm_start;
                stats.solver_objective = out.solver_objective;
                Ok(LayerResult {
                    evaluation: out.evaluation,
                    stopped: out.stopped,
                })
            }
            None => {
                let (evaluation, count) = enumeration::solve(problem, mode);
                stats.sequences += count;
                Ok(LayerResult {
                    evaluation,
                    stopped: false,
                })
            }
        }
    }
}

/// The set-point of a plan's first step: the acceleration that takes the ego from its
/// current speed to the step's speed in one period.
fn setpoint_of(problem: &Problem, first: &PlanStep) -> SetPoint {
    SetPoint {
        accel_mps2: (first.v_mps - problem.ego.v) / problem.kin.dt,
        target_speed_mps: first.v_mps,
    }
}

/// Layer B's decision: keep the target lane, set `beta` from the most critical threat
/// (`choice`, [`fallback::choose`] on this situation and its refreshed memory).
pub(crate) fn fallback_decision(
    config: &PlannerConfig,
    situation: &Situation,
    problem: &Problem,
    choice: &fallback::FallbackChoice,
    mut stats: SolveStats,
    mut memory: crate::types::PlannerMemory,
) -> Decision {
    let choice = *choice;
    stats.fallback_threat = Some(choice.threat);
    memory.previous_plan.clear();
    let start = situation.ego.maneuver;
    let next = Maneuver {
        lane: fallback::lateral_target(config, situation, &choice),
        beta: choice.beta,
    };
    // The fallback may go from accelerating straight to braking (an emergency does not wait a
    // step in cruise); the action, a change in -1..=1, then says "decelerate" and the next
    // maneuver carries the braking.
    let first = Action {
        lateral: (i16::from(next.lane) - i16::from(start.lane)).signum() as i8,
        longitudinal: (choice.beta - start.beta).clamp(-1, 1),
    };
    let accel = fallback::acceleration(&problem.kin, &choice, config.ego.emergency_decel_mps2);
    let (mut x, mut v) = (situation.ego.x_m, situation.ego.v_mps);
    let mut occupancy = problem.ego.occupancy;
    let plan: Vec<PlanStep> = (0..config.timing.horizon)
        .map(|h| {
            (x, v) = problem.kin.step_with(x, v, accel);
            v = v.clamp(0.0, problem.speed_cap);
            occupancy = occupancy.with(next.lane);
            PlanStep {
                action: if h == 0 { first } else { Action::KEEP },
                maneuver: next,
                x_m: x,
                v_mps: v,
                occupied_lanes: occupancy.0,
            }
        })
        .collect();
    debug_assert!(transition(next, Action::KEEP, problem.lanes).is_some());
    Decision {
        action: first,
        next_maneuver: next,
        setpoint: SetPoint {
            accel_mps2: accel,
            target_speed_mps: plan[0].v_mps,
        },
        plan,
        layer: Layer::Fallback,
        stats,
        memory,
    }
}

/// The fallback decision for a validated situation, without solving: what a watchdog answers
/// when a solve overruns, and what a vehicle does when no answer comes.
pub fn fallback_only(config: &PlannerConfig, situation: &ValidSituation) -> Decision {
    let started = Instant::now();
    let situation = situation.get();
    let prepared = prepare(config, situation);
    let stats = SolveStats {
        svs_considered: prepared.problem.svs.len(),
        corrective_svs: prepared.memory.corrective.len(),
        interrupted: true,
        ..SolveStats::new(config.solver.backend)
    };
    let choice = fallback::choose(
        config,
        situation,
        prepared.problem.ego.occupancy,
        &prepared.memory.corrective,
    );
    let mut d = fallback_decision(
        config,
        situation,
        &prepared.problem,
        &choice,
        stats,
        prepared.memory.clone(),
    );
    d.stats.total_us = started.elapsed().as_micros() as u64;
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{EgoState, Maneuver, PlannerMemory, Road};

    fn cruising(previous_plan: Vec<Action>) -> Situation {
        Situation {
            road: Road {
                lanes: 3,
                lane_width_m: 4.0,
                speed_limit_mps: 40.0,
            },
            ego: EgoState {
                x_m: 0.0,
                y_m: 4.0,
                v_mps: 25.0,
                desired_speed_mps: 25.0,
                maneuver: Maneuver { lane: 2, beta: 0 },
            },
            svs: Vec::new(),
            memory: PlannerMemory {
                previous_plan,
                ..PlannerMemory::default()
            },
        }
    }

    #[test]
    fn warm_candidates_are_the_shifted_plan_and_keep_everything_once_each() {
        let planner = Planner::new(PlannerConfig::default()).unwrap();
        let keep = vec![Action::KEEP; 3];
        // Cruising: the shifted plan is "keep everything" itself.
        assert_eq!(planner.warm_candidates(&cruising(keep.clone())), vec![keep.clone()]);
        let brake = Action {
            lateral: 0,
            longitudinal: -1,
        };
        let plan = vec![Action::KEEP, brake, Action::KEEP];
        let shifted = vec![brake, Action::KEEP, Action::KEEP];
        assert_eq!(planner.warm_candidates(&cruising(plan)), vec![shifted, keep.clone()]);
        assert_eq!(planner.warm_candidates(&cruising(Vec::new())), vec![keep]);
    }
}
