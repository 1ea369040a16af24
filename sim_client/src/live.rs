//! `sim_client case1 --foxglove [ADDR]`: the simulated world live in Foxglove, on the
//! channels of a recording (`/sim/trial`, `/sim/vehicles`, `/sim/decision`, `/sim/scene`,
//! docs/recording.md), published from the episode loop as a [`StepObserver`], paced at real
//! time unless asked to run as fast as it can.
//!
//! Log times (and the scene's stamps) are wall-clock: the time of the first step plus the
//! simulated time, so that with real-time pacing a message's time is when it was sent.

use std::time::{Duration, Instant};

use live_view::{LiveChannel, LiveOptions, LiveServer};
use recording::scene::{PlannedStep, SceneRoad};
use recording::WallClock;
use traffic::World;

use crate::episode::{DecisionRecord, StepObserver};
use crate::error::Result;
use crate::record::{
    channels, nanos, planned_steps, scene_road, step_scene, vehicle_states, SimDecision, TrialInfo, DECISION_TOPIC,
    SCENE_TOPIC, TRIAL_TOPIC, VEHICLES_TOPIC,
};

/// How fast the live run goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// One simulated second per second (the default: a person watches).
    RealTime,
    /// As fast as the simulation and the planner go.
    Fast,
}

/// The live view of one trial (as a [`StepObserver`]).
pub struct LiveTrial {
    server: LiveServer,
    trial: LiveChannel,
    vehicles: LiveChannel,
    decision: LiveChannel,
    scene: LiveChannel,
    info: TrialInfo,
    road: SceneRoad,
    pace: Pace,
    /// The first step's instant and wall-clock time (ns), set by the first step.
    origin: Option<(Instant, u64)>,
    /// `/sim/trial` again every this many steps (a viewer that connects late gets it).
    trial_every: u64,
    plan: Vec<PlannedStep>,
    corrective: Vec<u32>,
}

impl std::fmt::Debug for LiveTrial {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveTrial")
            .field("server", &self.server)
            .field("pace", &self.pace)
            .finish_non_exhaustive()
    }
}

impl LiveTrial {
    /// Starts serving the trial `info` describes.
    pub fn start(options: &LiveOptions, info: TrialInfo, pace: Pace) -> Result<Self> {
        let server = LiveServer::start(options, &channels())?;
        let channel = |topic| server.channel(topic).expect("a channel of the recording");
        let trial_every = (1.0 / info.low_level_step_s).round().max(1.0) as u64;
        Ok(Self {
            trial: channel(TRIAL_TOPIC),
            vehicles: channel(VEHICLES_TOPIC),
            decision: channel(DECISION_TOPIC),
            scene: channel(SCENE_TOPIC),
            road: scene_road(&info),
            server,
            info,
            pace,
            origin: None,
            trial_every,
            plan: Vec::new(),
            corrective: Vec::new(),
        })
    }

    /// The server (its address, subscribers, counters).
    pub fn server(&self) -> &LiveServer {
        &self.server
    }

    /// Publishes what is queued and stops; the final counters.
    pub fn finish(self) -> live_view::LiveCounters {
        self.server.finish()
    }

    /// The instant and wall-clock time of simulated time 0 (the first step's).
    fn origin(&mut self) -> (Instant, u64) {
        *self.origin.get_or_insert_with(|| {
            let now = Instant::now();
            (now, WallClock::now().ns(now))
        })
    }

    /// Waits until simulated time `time_s` is due (real-time pacing).
    fn pace(&mut self, time_s: f64) {
        let (start, _) = self.origin();
        if self.pace == Pace::RealTime && time_s.is_finite() && time_s > 0.0 {
            let due = start + Duration::from_secs_f64(time_s);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
    }

    /// Wall-clock ns of simulated time `time_s`.
    fn log_time(&mut self, time_s: f64) -> u64 {
        self.origin().1.saturating_add(nanos(time_s))
    }
}

impl StepObserver for LiveTrial {
    fn after_step(&mut self, world: &mut World) -> Result<()> {
        let states = vehicle_states(world);
        self.pace(states.time_s);
        let at = self.log_time(states.time_s);
        if states.step.is_multiple_of(self.trial_every) {
            self.server.publish_json(self.trial, at, self.info.clone());
        }
        if self.server.is_watched(self.scene) {
            let (road, plan, corrective, vehicles) = (
                self.road,
                self.plan.clone(),
                self.corrective.clone(),
                states.vehicles.clone(),
            );
            self.server.publish_with(self.scene, at, move || {
                recording::json::to_vec(&step_scene(at, road, &vehicles, &plan, &corrective))
            });
        }
        self.server.publish_json(self.vehicles, at, states);
        Ok(())
    }

    fn after_decision(&mut self, decision: &DecisionRecord) -> Result<()> {
        self.plan = planned_steps(decision);
        self.corrective.clone_from(&decision.corrective_sv_ids);
        if self.server.is_watched(self.decision) {
            let at = self.log_time(decision.time_s);
            let record = DecisionRecord {
                // The request is not part of the message.
                request: None,
                ..decision.clone()
            };
            self.server.publish_with(self.decision, at, move || {
                recording::json::to_vec(&SimDecision::of(&record))
            });
        }
        Ok(())
    }
}
