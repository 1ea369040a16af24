//! One closed-loop episode: the simulator and a driver (the planner through a
//! [`PlannerLink`], or the simulator's own IDM + MOBIL ego), decision by decision.
//!
//! Pure apart from the planner call: no I/O, no clock except the planner's own solve-time
//! statistic, which is kept apart from everything that must be reproducible.

use decision::PlanStep;
use protocol::{Layer, PlanRequest, WireError};
use serde::{Deserialize, Serialize};
use traffic::{EgoCommand, EgoMode, Perception, Scenario, SimParams, World};

use crate::error::{Result, SimClientError};
use crate::link::{LinkError, PlannerLink};
use crate::metrics::{clean, EpisodeMetrics};
use crate::safety::{
    classify_ego_collision, Body, EgoCollisionKind, SafetyAccumulator, SafetySummary, HARD_BRAKING_MPS2,
};

/// `|a|` below this counts as cruising when the IDM + MOBIL ego's longitudinal mode is
/// read off its acceleration (same dead band the planner uses for SVs), m/s^2.
pub const IDM_BETA_DEAD_BAND_MPS2: f64 = 0.3;

/// Who drives the ego.
pub enum Driver<'a> {
    /// The planner, reached through a link; the ego follows its commands.
    Planner(&'a mut dyn PlannerLink),
    /// The simulator's rule-based ego (IDM + MOBIL); no planner involved.
    IdmMobil,
}

impl Driver<'_> {
    fn ego_mode(&self) -> EgoMode {
        match self {
            Driver::Planner(_) => EgoMode::Commanded,
            Driver::IdmMobil => EgoMode::IdmMobil,
        }
    }
}

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeSpec {
    /// Initial scene.
    pub scenario: Scenario,
    /// Simulator parameters (T_l, T_h, SV behaviour, sensor range, ...).
    pub params: SimParams,
    /// Seed of the simulator's random stream.
    pub seed: u64,
    /// Simulated duration (s); the episode also ends at the first ego collision.
    pub duration_s: f64,
    /// At most this many SVs (the nearest) are sent to the planner.
    pub max_svs: usize,
    /// Record every vehicle's state after every low-level step, and the situation sent at
    /// every decision (for the figures).
    pub record_trajectory: bool,
    /// Classify every nominal decision against the plain MPC of this configuration (the
    /// driver's): no violation allowance, band slack within `d_HS`
    /// ([`decision::classify_nominal`]), so that the nominal share compares with the paper's.
    pub audit_nominal: Option<decision::PlannerConfig>,
    /// Keep every planner decision that brakes hard, with its situation
    /// ([`Episode::hard_braking`]).
    pub trace_hard_braking: bool,
}

/// A planner decision whose first step brakes at or below [`HARD_BRAKING_MPS2`], with the
/// situation it answered: what `decision`'s `explain_decision` example reads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HardBrakingDecision {
    /// Simulation time (s).
    pub time_s: f64,
    /// The answer's first-step acceleration, m/s^2.
    pub accel_mps2: f64,
    /// The layer that answered.
    pub layer: Layer,
    /// What the planner was asked.
    pub situation: decision::Situation,
}

/// One decision instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecisionRecord {
    /// Index of the decision (0, 1, ...).
    pub index: u64,
    /// Simulation time (s).
    pub time_s: f64,
    /// Layer that answered (`None` for the IDM + MOBIL ego).
    pub layer: Option<Layer>,
    /// Commanded target lane after this decision (IDM ego: its target lane).
    pub target_lane: u8,
    /// Commanded beta after this decision (IDM ego: sign of its acceleration, dead band
    /// [`IDM_BETA_DEAD_BAND_MPS2`]).
    pub beta: i8,
    /// SVs in corrective mode.
    pub corrective_svs: usize,
    /// Their ids, from the decision's memory (space-separated in the CSV).
    #[serde(with = "id_list")]
    pub corrective_sv_ids: Vec<u32>,
    /// SVs sent to the planner.
    pub svs_sent: usize,
    /// Ego position and speed at the decision instant.
    pub ego_x_m: f64,
    /// Ego lateral position (m).
    pub ego_y_m: f64,
    /// Ego speed (m/s).
    pub ego_speed_mps: f64,
    /// The planned maneuvers over the horizon (empty for the IDM ego).
    #[serde(skip)]
    pub plan: Vec<PlanStep>,
    /// Wall time of the planner's decision (µs); not reproducible, kept out of the CSV.
    #[serde(skip)]
    pub solve_us: u64,
    /// The request sent, ids and times aside (only with [`EpisodeSpec::record_trajectory`]).
    #[serde(skip)]
    pub request: Option<PlanRequest>,
    /// A nominal decision against the plain MPC (only with [`EpisodeSpec::audit_nominal`]).
    #[serde(skip)]
    pub nominal_class: Option<decision::NominalClass>,
}

/// A list of ids as one CSV cell: `"2 5"`.
mod id_list {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(ids: &[u32], s: S) -> Result<S::Ok, S::Error> {
        let text: Vec<String> = ids.iter().map(u32::to_string).collect();
        s.serialize_str(&text.join(" "))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u32>, D::Error> {
        let text = String::deserialize(d)?;
        text.split_whitespace()
            .map(|t| t.parse().map_err(serde::de::Error::custom))
            .collect()
    }
}

/// State of one vehicle after a low-level step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VehicleState {
    /// Low-level step index (0 = initial state).
    pub step: u64,
    /// Simulation time (s).
    pub time_s: f64,
    /// Vehicle id (0 = ego).
    pub id: u32,
    /// Longitudinal position (m).
    pub x_m: f64,
    /// Lateral position (m).
    pub y_m: f64,
    /// Speed (m/s).
    pub v_mps: f64,
    /// Acceleration (m/s^2).
    pub a_mps2: f64,
    /// Nearest lane.
    pub lane: u8,
    /// Lane it heads to.
    pub target_lane: u8,
    /// Longitudinal mode.
    pub beta: i8,
}

/// The first ego contact.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CollisionEvent {
    /// Time at the end of the step in which it happened (s).
    pub time_s: f64,
    /// The other vehicle's id.
    pub other_id: u32,
    /// Who caused it.
    pub kind: EgoCollisionKind,
}

/// Everything an episode produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    /// Decision period (s).
    pub decision_period_s: f64,
    /// Lane the ego started in.
    pub initial_lane: u8,
    /// One record per decision instant.
    pub decisions: Vec<DecisionRecord>,
    /// Vehicle states per step (empty unless asked for).
    pub trajectory: Vec<VehicleState>,
    /// First ego collision, if any (the episode stops there).
    pub collision: Option<CollisionEvent>,
    /// First contacts between two SVs until the episode stopped.
    pub sv_collisions: u32,
    /// Low-level steps simulated.
    pub steps: u64,
    /// Simulated time (s).
    pub simulated_s: f64,
    /// Sum of the ego speed after every step (for the mean).
    pub ego_speed_sum: f64,
    /// Surrogate safety measures over every step.
    pub safety: SafetySummary,
    /// The hard-braking decisions (with [`EpisodeSpec::trace_hard_braking`]).
    pub hard_braking: Vec<HardBrakingDecision>,
}

impl Episode {
    /// The episode's metrics.
    pub fn metrics(&self) -> EpisodeMetrics {
        EpisodeMetrics::from_episode(self)
    }

    /// Planner solve times (µs), one per planner decision.
    pub fn solve_times_us(&self) -> Vec<u64> {
        self.decisions
            .iter()
            .filter(|d| d.layer.is_some())
            .map(|d| d.solve_us)
            .collect()
    }
}

/// The request body for the perceived scene, as a vehicle sends it: road, ego with its last
/// commanded maneuver, the `max_svs` nearest SVs (sorted by id) and the memory of the last
/// answer, handed back as it came. Ids, time and deadline are the link's to fill in.
pub fn request_from(
    perception: &Perception,
    command: EgoCommand,
    max_svs: usize,
    memory: protocol::PlannerMemory,
) -> std::result::Result<PlanRequest, WireError> {
    let ego = &perception.ego;
    let mut svs: Vec<&traffic::SvObservation> = perception.svs.iter().collect();
    svs.sort_by(|a, b| {
        let da = ((a.x - ego.x).abs(), (a.y - ego.y).abs(), a.id);
        let db = ((b.x - ego.x).abs(), (b.y - ego.y).abs(), b.id);
        da.0.total_cmp(&db.0).then(da.1.total_cmp(&db.1)).then(da.2.cmp(&db.2))
    });
    svs.truncate(max_svs);
    svs.sort_by_key(|s| s.id);
    let svs: Vec<protocol::SvObservation> = svs
        .into_iter()
        .map(|s| protocol::SvObservation {
            vy_mps: s.vy,
            ..protocol::SvObservation::new(s.id, s.x, s.y, s.v, s.a)
        })
        .collect();
    let road = protocol::Road {
        lanes: perception.road.lanes,
        lane_width_m: perception.road.lane_width,
        speed_limit_mps: perception.road.speed_limit,
    };
    let ego = protocol::EgoState {
        x_m: ego.x,
        y_m: ego.y,
        v_mps: ego.v,
        desired_speed_mps: ego.desired_speed,
        maneuver: protocol::Maneuver {
            lane: command.target_lane,
            beta: command.beta,
        },
    };
    Ok(PlanRequest {
        svs: protocol::bounded("svs", &svs)?,
        memory,
        ..PlanRequest::new(0, 0, 0, road, ego)
    })
}

/// [`decision::classify_nominal`] of a nominal answer to `request`.
fn classify(
    config: &decision::PlannerConfig,
    request: &PlanRequest,
    planned: &crate::link::Planned,
) -> Result<decision::NominalClass> {
    let situation = decision::ValidSituation::new(config, &request.to_situation())
        .map_err(|e| SimClientError::Config(format!("auditing a nominal decision: {e}")))?;
    let plan: Vec<decision::Action> = planned.plan.iter().map(|s| s.action).collect();
    Ok(decision::classify_nominal(config, &situation, &plan))
}

fn beta_of_acceleration(a: f64) -> i8 {
    if a > IDM_BETA_DEAD_BAND_MPS2 {
        1
    } else if a < -IDM_BETA_DEAD_BAND_MPS2 {
        -1
    } else {
        0
    }
}

fn record_states(world: &World, out: &mut Vec<VehicleState>) {
    let (step, time_s) = (world.step_index(), clean(world.time()));
    out.extend(world.vehicles().iter().map(|v| VehicleState {
        step,
        time_s,
        id: v.id,
        x_m: v.x,
        y_m: v.y,
        v_mps: v.v,
        a_mps2: v.a,
        lane: v.lane,
        target_lane: v.target_lane,
        beta: v.beta,
    }));
}

/// Sees (and may change) the world after its initial state and after every low-level step,
/// before the step is scored, and sees every decision: how a recording captures the ground
/// truth, how a log replay puts the SVs on their recorded trajectories and how the live view
/// (`sim_client case1 --foxglove`) shows the run while it goes.
pub trait StepObserver {
    /// Called with the world after step `world.step_index()`.
    fn after_step(&mut self, world: &mut World) -> Result<()>;

    /// Called with every decision as it is taken, before the steps it commands.
    fn after_decision(&mut self, _decision: &DecisionRecord) -> Result<()> {
        Ok(())
    }

    /// Called once when the episode ends (its duration, or the ego's collision).
    fn at_end(&mut self) -> Result<()> {
        Ok(())
    }
}

/// Observes nothing.
impl StepObserver for () {
    fn after_step(&mut self, _world: &mut World) -> Result<()> {
        Ok(())
    }
}

impl<T: StepObserver + ?Sized> StepObserver for &mut T {
    fn after_step(&mut self, world: &mut World) -> Result<()> {
        (**self).after_step(world)
    }

    fn after_decision(&mut self, decision: &DecisionRecord) -> Result<()> {
        (**self).after_decision(decision)
    }

    fn at_end(&mut self) -> Result<()> {
        (**self).at_end()
    }
}

/// Both observers, the first first (e.g. a recording and the live view).
impl<A: StepObserver, B: StepObserver> StepObserver for (A, B) {
    fn after_step(&mut self, world: &mut World) -> Result<()> {
        self.0.after_step(world)?;
        self.1.after_step(world)
    }

    fn after_decision(&mut self, decision: &DecisionRecord) -> Result<()> {
        self.0.after_decision(decision)?;
        self.1.after_decision(decision)
    }

    fn at_end(&mut self) -> Result<()> {
        self.0.at_end()?;
        self.1.at_end()
    }
}

/// Runs one episode to its duration or to the first ego collision.
pub fn run_episode(spec: &EpisodeSpec, driver: Driver<'_>) -> Result<Episode> {
    run_episode_observed(spec, driver, &mut ())
}

/// [`run_episode`] with an observer of every step.
pub fn run_episode_observed(
    spec: &EpisodeSpec,
    mut driver: Driver<'_>,
    observer: &mut dyn StepObserver,
) -> Result<Episode> {
    if !(spec.duration_s.is_finite() && spec.duration_s > 0.0) {
        return Err(SimClientError::Config("episode duration must be positive".into()));
    }
    let mut world = World::new(&spec.scenario, &spec.params, driver.ego_mode(), spec.seed)?;
    let steps_per_decision = spec.params.steps_per_decision();
    let total_steps = (spec.duration_s / spec.params.dt).round() as u64;
    let mut episode = Episode {
        decision_period_s: spec.params.dt * steps_per_decision as f64,
        initial_lane: spec.scenario.ego.lane,
        decisions: Vec::with_capacity((total_steps / steps_per_decision + 1) as usize),
        trajectory: Vec::new(),
        collision: None,
        sv_collisions: 0,
        steps: 0,
        simulated_s: 0.0,
        ego_speed_sum: 0.0,
        safety: SafetySummary::default(),
        hard_braking: Vec::new(),
    };
    observer.after_step(&mut world)?;
    let mut safety = SafetyAccumulator::for_world(&world);
    if spec.record_trajectory {
        record_states(&world, &mut episode.trajectory);
    }
    let mut memory = protocol::PlannerMemory::default();
    while world.step_index() < total_steps {
        if world.step_index() % steps_per_decision == 0 {
            let perception = world.perceive();
            let index = episode.decisions.len() as u64;
            let record = match &mut driver {
                Driver::Planner(link) => {
                    let request = request_from(
                        &perception,
                        world.ego_command(),
                        spec.max_svs,
                        std::mem::take(&mut memory),
                    )
                    .map_err(LinkError::Encode)?;
                    let decision = link.decide(&request)?;
                    let m = decision.next_maneuver;
                    world.set_ego_command_with_accel(
                        EgoCommand {
                            target_lane: m.lane,
                            beta: m.beta,
                        },
                        decision.setpoint.accel_mps2,
                    )?;
                    if spec.trace_hard_braking && decision.setpoint.accel_mps2 <= HARD_BRAKING_MPS2 {
                        episode.hard_braking.push(HardBrakingDecision {
                            time_s: clean(perception.time),
                            accel_mps2: decision.setpoint.accel_mps2,
                            layer: decision.layer,
                            situation: request.to_situation(),
                        });
                    }
                    let corrective_sv_ids = decision.memory.corrective.iter().map(|c| c.sv_id).collect();
                    let nominal_class = match &spec.audit_nominal {
                        Some(config) if decision.layer == Layer::Nominal => {
                            Some(classify(config, &request, &decision)?)
                        }
                        _ => None,
                    };
                    memory = decision.memory;
                    DecisionRecord {
                        index,
                        time_s: clean(perception.time),
                        layer: Some(decision.layer),
                        target_lane: m.lane,
                        beta: m.beta,
                        corrective_svs: decision.corrective_svs,
                        corrective_sv_ids,
                        svs_sent: request.svs.len(),
                        ego_x_m: perception.ego.x,
                        ego_y_m: perception.ego.y,
                        ego_speed_mps: perception.ego.v,
                        plan: decision.plan,
                        solve_us: decision.solve_us,
                        request: spec.record_trajectory.then_some(request),
                        nominal_class,
                    }
                }
                Driver::IdmMobil => DecisionRecord {
                    index,
                    time_s: clean(perception.time),
                    layer: None,
                    target_lane: perception.ego.target_lane,
                    beta: beta_of_acceleration(perception.ego.a),
                    corrective_svs: 0,
                    corrective_sv_ids: Vec::new(),
                    svs_sent: 0,
                    ego_x_m: perception.ego.x,
                    ego_y_m: perception.ego.y,
                    ego_speed_mps: perception.ego.v,
                    plan: Vec::new(),
                    solve_us: 0,
                    request: None,
                    nominal_class: None,
                },
            };
            observer.after_decision(&record)?;
            episode.decisions.push(record);
        }
        let collisions = world.step();
        observer.after_step(&mut world)?;
        episode.ego_speed_sum += world.ego().v;
        let bodies = Body::all(&world);
        safety.observe(&bodies);
        if spec.record_trajectory {
            record_states(&world, &mut episode.trajectory);
        }
        episode.sv_collisions += collisions.iter().filter(|c| !c.involves_ego && c.first_contact).count() as u32;
        if let Some(c) = collisions.iter().find(|c| c.involves_ego && c.first_contact) {
            let other_id = if c.a == traffic::EGO_ID { c.b } else { c.a };
            let other = bodies
                .iter()
                .find(|b| b.id == other_id)
                .expect("a colliding vehicle exists");
            episode.collision = Some(CollisionEvent {
                time_s: clean(world.time()),
                other_id,
                kind: classify_ego_collision(&bodies[0], other),
            });
            break;
        }
    }
    observer.at_end()?;
    episode.safety = safety.summary();
    episode.steps = world.step_index();
    episode.simulated_s = world.time();
    Ok(episode)
}
