use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::{
    idm_acceleration, jerk_limited_acceleration, mobil_evaluate, rectangles_overlap, Collision, EgoObservation,
    LaneChange, LaneSet, MobilDecision, MobilInput, Perception, Road, Scenario, SimError, SimParams, SvObservation,
    Vehicle, VehicleInit, VehicleKind, EGO_ID, VEHICLE_LENGTH,
};

/// How the ego is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum EgoMode {
    /// Follows the last [`EgoCommand`] (the planner under test drives).
    Commanded,
    /// Drives itself with IDM + MOBIL and no random switches (rule-based baseline), with the
    /// commanded ego's jerk and speed bounds: the same vehicle, another driver.
    IdmMobil,
}

/// High-level command for the ego: lane to drive in and longitudinal mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct EgoCommand {
    /// Lane to drive to, `1..=lanes`.
    pub target_lane: u8,
    /// -1 brake (a_dec), 0 hold speed, +1 accelerate (a_acc).
    pub beta: i8,
}

/// Serializable full state of a [`World`], including the RNG position, so a run can be
/// logged, compared bit for bit and resumed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorldSnapshot {
    /// Low-level steps taken so far.
    pub step_index: u64,
    /// Simulation time (s), `step_index * dt`.
    pub time: f64,
    /// Road geometry and speed limit.
    pub road: Road,
    /// Parameters in use.
    pub params: SimParams,
    /// How the ego is driven.
    pub ego_mode: EgoMode,
    /// Last ego command.
    pub ego_command: EgoCommand,
    /// Acceleration set-point that goes with it, if the driver gave one.
    #[serde(default)]
    pub ego_accel_setpoint: Option<f64>,
    /// Ego first, then SVs by increasing id.
    pub vehicles: Vec<Vehicle>,
    /// Pairs `(smaller id, larger id)` overlapping at the end of the last step.
    pub contacts: Vec<(u32, u32)>,
    /// Random stream of the SV behaviour.
    pub rng: ChaCha8Rng,
}

/// The traffic simulator.
#[derive(Debug, Clone)]
pub struct World {
    road: Road,
    params: SimParams,
    ego_mode: EgoMode,
    ego_command: EgoCommand,
    ego_accel_setpoint: Option<f64>,
    vehicles: Vec<Vehicle>,
    contacts: Vec<(u32, u32)>,
    step_index: u64,
    rng: ChaCha8Rng,
}

fn check_init(road: &Road, id: u32, init: &VehicleInit) -> Result<(), SimError> {
    road.check_lane(init.lane)?;
    if !init.x.is_finite() {
        return Err(SimError::InvalidParameter {
            name: "vehicle.x",
            reason: "must be finite",
        });
    }
    if !(init.v.is_finite() && init.v >= 0.0) {
        return Err(SimError::InvalidParameter {
            name: "vehicle.v",
            reason: "must be finite and non-negative",
        });
    }
    if !(init.desired_speed.is_finite() && init.desired_speed > 0.0) {
        return Err(SimError::InvalidParameter {
            name: "vehicle.desired_speed",
            reason: "must be finite and positive",
        });
    }
    if id == EGO_ID && init.v > road.speed_limit {
        return Err(SimError::InvalidParameter {
            name: "ego.v",
            reason: "exceeds the speed limit",
        });
    }
    Ok(())
}

impl World {
    /// Builds a world from a scenario; `seed` drives all SV randomness.
    pub fn new(scenario: &Scenario, params: &SimParams, ego_mode: EgoMode, seed: u64) -> Result<Self, SimError> {
        let road = scenario.road;
        road.validate()?;
        params.validate()?;
        let inits = std::iter::once(&scenario.ego).chain(scenario.svs.iter());
        let mut vehicles = Vec::with_capacity(scenario.svs.len() + 1);
        for (id, init) in (0u32..).zip(inits) {
            check_init(&road, id, init)?;
            let (kind, beta) = match (id, ego_mode) {
                (EGO_ID, EgoMode::Commanded) => (VehicleKind::Ego, 0),
                (EGO_ID, EgoMode::IdmMobil) => (VehicleKind::Ego, 1),
                _ => (VehicleKind::Surrounding, 1),
            };
            vehicles.push(Vehicle {
                id,
                kind,
                x: init.x,
                y: road.lane_centre(init.lane),
                vy: 0.0,
                v: init.v,
                a: 0.0,
                lane: init.lane,
                target_lane: init.lane,
                lane_change: None,
                desired_speed: init.desired_speed,
                beta,
            });
        }
        let contacts = overlapping_pairs(&vehicles);
        if let Some(&(a, b)) = contacts.first() {
            return Err(SimError::InitialOverlap { a, b });
        }
        Ok(World {
            road,
            params: *params,
            ego_mode,
            ego_command: EgoCommand {
                target_lane: scenario.ego.lane,
                beta: 0,
            },
            ego_accel_setpoint: None,
            vehicles,
            contacts,
            step_index: 0,
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }

    /// Resumes a world from a snapshot.
    pub fn from_snapshot(s: WorldSnapshot) -> Result<Self, SimError> {
        s.road.validate()?;
        s.params.validate()?;
        if s.vehicles.first().map(|v| v.id) != Some(EGO_ID) {
            return Err(SimError::InvalidParameter {
                name: "vehicles",
                reason: "the ego (id 0) must come first",
            });
        }
        Ok(World {
            road: s.road,
            params: s.params,
            ego_mode: s.ego_mode,
            ego_command: s.ego_command,
            ego_accel_setpoint: s.ego_accel_setpoint,
            vehicles: s.vehicles,
            contacts: s.contacts,
            step_index: s.step_index,
            rng: s.rng,
        })
    }

    /// Full state for logs and determinism checks.
    pub fn snapshot(&self) -> WorldSnapshot {
        WorldSnapshot {
            step_index: self.step_index,
            time: self.time(),
            road: self.road,
            params: self.params,
            ego_mode: self.ego_mode,
            ego_command: self.ego_command,
            ego_accel_setpoint: self.ego_accel_setpoint,
            vehicles: self.vehicles.clone(),
            contacts: self.contacts.clone(),
            rng: self.rng.clone(),
        }
    }

    /// Simulation time (s); computed from the step count so it does not drift.
    pub fn time(&self) -> f64 {
        self.step_index as f64 * self.params.dt
    }

    /// Low-level steps taken so far.
    pub fn step_index(&self) -> u64 {
        self.step_index
    }

    /// The road.
    pub fn road(&self) -> &Road {
        &self.road
    }

    /// The parameters in use.
    pub fn params(&self) -> &SimParams {
        &self.params
    }

    /// How the ego is driven.
    pub fn ego_mode(&self) -> EgoMode {
        self.ego_mode
    }

    /// Last command given to the ego (initially: keep lane, beta = 0).
    pub fn ego_command(&self) -> EgoCommand {
        self.ego_command
    }

    /// All vehicles: the ego first, then SVs by increasing id.
    pub fn vehicles(&self) -> &[Vehicle] {
        &self.vehicles
    }

    /// The ego vehicle.
    pub fn ego(&self) -> &Vehicle {
        &self.vehicles[0]
    }

    /// Vehicle with the given id, if present.
    pub fn vehicle(&self, id: u32) -> Option<&Vehicle> {
        self.vehicles.iter().find(|v| v.id == id)
    }

    /// Sets the ego's high-level command; takes effect at once.
    ///
    /// A target lane different from the one the ego is heading to starts a new smooth
    /// lateral manoeuvre from its current `y`, lasting `T_lc` per lane width of lateral
    /// distance (at least `min_lane_change_duration`).
    pub fn set_ego_command(&mut self, cmd: EgoCommand) -> Result<(), SimError> {
        if self.ego_mode != EgoMode::Commanded {
            return Err(SimError::EgoNotCommanded);
        }
        self.road.check_lane(cmd.target_lane)?;
        if !(-1..=1).contains(&cmd.beta) {
            return Err(SimError::InvalidBeta(cmd.beta));
        }
        self.ego_command = cmd;
        self.ego_accel_setpoint = None;
        let road = self.road;
        let p = self.params;
        let ego = &mut self.vehicles[0];
        ego.beta = cmd.beta;
        if cmd.target_lane != ego.target_lane {
            let to_y = road.lane_centre(cmd.target_lane);
            let dy = (to_y - ego.y).abs();
            let duration = (p.lane_change_duration * dy / road.lane_width).max(p.min_lane_change_duration);
            ego.lane_change = Some(LaneChange {
                origin_lane: road.lane_of(ego.y),
                target_lane: cmd.target_lane,
                from_y: ego.y,
                to_y,
                duration,
                steps_elapsed: 0,
            });
            ego.target_lane = cmd.target_lane;
        }
        Ok(())
    }

    /// Sets the command with an acceleration set-point: the ego tracks `accel` (jerk-limited,
    /// within `[idm.a_min, a_acc]`) instead of the fixed acceleration of `cmd.beta`.
    pub fn set_ego_command_with_accel(&mut self, cmd: EgoCommand, accel: f64) -> Result<(), SimError> {
        if !accel.is_finite() {
            return Err(SimError::InvalidParameter {
                name: "ego accel set-point",
                reason: "must be finite",
            });
        }
        self.set_ego_command(cmd)?;
        self.ego_accel_setpoint = Some(accel);
        Ok(())
    }

    /// What the ego's perception stack reports now.
    pub fn perceive(&self) -> Perception {
        let ego = self.ego();
        let range = self.params.sensor_range;
        Perception {
            time: self.time(),
            road: self.road,
            ego: EgoObservation {
                x: ego.x,
                y: ego.y,
                v: ego.v,
                a: ego.a,
                lane: ego.lane,
                target_lane: ego.target_lane,
                desired_speed: ego.desired_speed,
            },
            svs: self.vehicles[1..]
                .iter()
                .filter(|s| (s.x - ego.x).abs() <= range)
                .map(|s| SvObservation {
                    id: s.id,
                    x: s.x,
                    y: s.y,
                    v: s.v,
                    a: s.a,
                    vy: s.vy,
                })
                .collect(),
        }
    }

    /// Advances the simulation by one low-level step `dt`.
    ///
    /// At decision instants (every `decision_period`, starting at t = 0) the SVs (and the
    /// ego in [`EgoMode::IdmMobil`]) first update their modes and lane-change decisions.
    /// Returns every pair of vehicles whose rectangles overlap after the step; the
    /// simulation continues regardless.
    pub fn step(&mut self) -> Vec<Collision> {
        if self.step_index.is_multiple_of(self.params.steps_per_decision()) {
            self.decide();
        }
        let sets = self.lane_sets();
        let accels: Vec<f64> = (0..self.vehicles.len())
            .map(|i| self.commanded_acceleration(i, &sets))
            .collect();
        let dt = self.params.dt;
        let road = self.road;
        for (veh, a) in self.vehicles.iter_mut().zip(accels) {
            let is_ego = veh.kind == VehicleKind::Ego;
            integrate_longitudinal(veh, a, dt, is_ego.then_some(road.speed_limit));
            advance_lateral(veh, &road, dt);
        }
        self.step_index += 1;
        self.collisions()
    }

    fn collisions(&mut self) -> Vec<Collision> {
        let now = overlapping_pairs(&self.vehicles);
        let out = now
            .iter()
            .map(|&(a, b)| Collision {
                a,
                b,
                involves_ego: a == EGO_ID || b == EGO_ID,
                first_contact: !self.contacts.contains(&(a, b)),
            })
            .collect();
        self.contacts = now;
        out
    }

    /// Lanes each vehicle occupies (see [`Vehicle::lane_set`]), in [`World::vehicles`] order:
    /// the sets leader search, IDM and MOBIL use.
    pub fn lane_sets(&self) -> Vec<LaneSet> {
        self.vehicles.iter().map(|v| v.lane_set(&self.road)).collect()
    }

    /// Whether vehicle `j` is ahead of `i` (ties in x broken by id for determinism).
    fn is_ahead(&self, j: usize, i: usize) -> bool {
        let (a, b) = (&self.vehicles[j], &self.vehicles[i]);
        (a.x, a.id) > (b.x, b.id)
    }

    /// Closest vehicle ahead of `i` present in `lane`.
    fn leader_in_lane(&self, i: usize, lane: u8, sets: &[LaneSet]) -> Option<usize> {
        (0..self.vehicles.len())
            .filter(|&j| j != i && sets[j].contains(lane) && self.is_ahead(j, i))
            .min_by(|&a, &b| self.order(a, b))
    }

    /// Closest vehicle behind `i` present in `lane`.
    fn follower_in_lane(&self, i: usize, lane: u8, sets: &[LaneSet]) -> Option<usize> {
        (0..self.vehicles.len())
            .filter(|&j| j != i && sets[j].contains(lane) && self.is_ahead(i, j))
            .max_by(|&a, &b| self.order(a, b))
    }

    fn order(&self, a: usize, b: usize) -> std::cmp::Ordering {
        let (va, vb) = (&self.vehicles[a], &self.vehicles[b]);
        va.x.total_cmp(&vb.x).then(va.id.cmp(&vb.id))
    }

    /// IDM acceleration of `i` behind `leader` (free road when `None`).
    fn idm_behind(&self, i: usize, leader: Option<usize>) -> f64 {
        let f = &self.vehicles[i];
        let (gap, dv) = match leader {
            Some(l) => {
                let l = &self.vehicles[l];
                (l.x - f.x - VEHICLE_LENGTH, f.v - l.v)
            }
            None => (f64::INFINITY, 0.0),
        };
        idm_acceleration(f.v, f.desired_speed, gap, dv, &self.params.idm)
    }

    /// IDM acceleration of `i` given everybody's lane sets: the most restrictive of the
    /// closest leaders in each lane `i` occupies (origin and target during a change).
    fn idm_in_lanes(&self, i: usize, sets: &[LaneSet]) -> f64 {
        sets[i]
            .iter()
            .map(|lane| self.idm_behind(i, self.leader_in_lane(i, lane, sets)))
            .fold(f64::INFINITY, f64::min)
    }

    /// Acceleration vehicle `i` asks for in this step.
    fn commanded_acceleration(&self, i: usize, sets: &[LaneSet]) -> f64 {
        let v = &self.vehicles[i];
        let p = &self.params;
        match (v.kind, self.ego_mode) {
            // One vehicle whoever drives it: the driver picks the target, the vehicle's
            // jerk and speed bounds apply to both.
            (VehicleKind::Ego, mode) => {
                let target = match (mode, self.ego_accel_setpoint, v.beta) {
                    (EgoMode::IdmMobil, _, _) => self.idm_in_lanes(i, sets),
                    // The physical limits every vehicle has (IDM's strongest braking).
                    (EgoMode::Commanded, Some(a), _) => a.clamp(p.idm.a_min, p.a_acc),
                    (EgoMode::Commanded, None, 1) => p.a_acc,
                    (EgoMode::Commanded, None, -1) => p.a_dec,
                    (EgoMode::Commanded, None, _) => 0.0,
                };
                jerk_limited_acceleration(v.v, self.road.speed_limit, v.a, target, p.jerk_max, p.dt)
            }
            (VehicleKind::Surrounding, _) => {
                let idm = self.idm_in_lanes(i, sets);
                match v.beta {
                    1 => idm,
                    0 => idm.min(0.0),
                    _ => idm.min(-p.sv.gentle_decel),
                }
            }
        }
    }

    /// MOBIL quantities for vehicle `i` moving from its lane to `target`.
    fn mobil_candidate(&self, i: usize, target: u8, sets: &[LaneSet]) -> MobilDecision {
        let c = &self.vehicles[i];
        let mut after = sets.to_vec();
        after[i] = LaneSet::single(target);
        let pair = |j: Option<usize>| {
            j.map_or((0.0, 0.0), |j| {
                (self.idm_in_lanes(j, sets), self.idm_in_lanes(j, &after))
            })
        };
        let n = self.follower_in_lane(i, target, sets);
        let o = self.follower_in_lane(i, c.lane, sets);
        let (a_n, a_n_new) = pair(n);
        let (a_o, a_o_new) = pair(o);
        let input = MobilInput {
            a_c: self.idm_in_lanes(i, sets),
            a_c_new: self.idm_in_lanes(i, &after),
            a_n,
            a_n_new,
            a_o,
            a_o_new,
            gap_new_leader: self
                .leader_in_lane(i, target, sets)
                .map(|l| self.vehicles[l].x - c.x - VEHICLE_LENGTH),
            gap_new_follower: n.map(|f| c.x - self.vehicles[f].x - VEHICLE_LENGTH),
        };
        mobil_evaluate(&input, &self.params.mobil)
    }

    fn start_lane_change(&mut self, i: usize, target: u8) {
        let road = self.road;
        let duration = self.params.lane_change_duration;
        let v = &mut self.vehicles[i];
        v.lane_change = Some(LaneChange {
            origin_lane: v.lane,
            target_lane: target,
            from_y: v.y,
            to_y: road.lane_centre(target),
            duration,
            steps_elapsed: 0,
        });
        v.target_lane = target;
    }

    /// Best accepted MOBIL change for `i` (largest incentive; left wins ties).
    fn mobil_choice(&self, i: usize, sets: &[LaneSet]) -> Option<u8> {
        let lane = self.vehicles[i].lane;
        self.road
            .neighbours(lane)
            .map(|t| (t, self.mobil_candidate(i, t, sets)))
            .filter(|(_, d)| d.accepted())
            .fold(None, |best: Option<(u8, f64)>, (t, d)| match best {
                Some((_, inc)) if inc >= d.incentive => best,
                _ => Some((t, d.incentive)),
            })
            .map(|(t, _)| t)
    }

    /// Decision instant: HMDP mode switches and lane-change decisions, vehicle by vehicle
    /// in id order so each decision sees the lane changes started before it.
    fn decide(&mut self) {
        let sv = self.params.sv;
        for i in 0..self.vehicles.len() {
            match (self.vehicles[i].kind, self.ego_mode) {
                (VehicleKind::Ego, EgoMode::Commanded) => continue,
                (VehicleKind::Ego, EgoMode::IdmMobil) => {
                    if !self.vehicles[i].is_changing_lanes() {
                        let sets = self.lane_sets();
                        if let Some(t) = self.mobil_choice(i, &sets) {
                            self.start_lane_change(i, t);
                        }
                    }
                    continue;
                }
                (VehicleKind::Surrounding, _) => {}
            }
            // Always draw the same four numbers so the stream does not depend on outcomes.
            let u_keep: f64 = self.rng.random();
            let u_dir: f64 = self.rng.random();
            let u_lat: f64 = self.rng.random();
            let u_side: f64 = self.rng.random();
            let veh = &mut self.vehicles[i];
            if u_keep >= sv.p_keep_long {
                veh.beta = match veh.beta {
                    0 if u_dir < 0.5 => -1,
                    0 => 1,
                    _ => 0,
                };
            }
            if veh.is_changing_lanes() {
                continue;
            }
            let sets = self.lane_sets();
            if u_lat < sv.p_random_lane_change {
                let options: Vec<u8> = self.road.neighbours(self.vehicles[i].lane).collect();
                let pick = if options.len() == 2 && u_side >= 0.5 {
                    options[1]
                } else {
                    options[0]
                };
                if self.mobil_candidate(i, pick, &sets).safe {
                    self.start_lane_change(i, pick);
                    continue;
                }
            }
            if let Some(t) = self.mobil_choice(i, &sets) {
                self.start_lane_change(i, t);
            }
        }
    }
}

/// Pairs `(smaller id, larger id)` whose rectangles overlap.
fn overlapping_pairs(vehicles: &[Vehicle]) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for (k, a) in vehicles.iter().enumerate() {
        for b in &vehicles[k + 1..] {
            if rectangles_overlap((a.x, a.y), (b.x, b.y)) {
                out.push((a.id.min(b.id), a.id.max(b.id)));
            }
        }
    }
    out
}

/// Constant-acceleration update over one step; the speed never goes below zero, and
/// never above `v_max` when given. `v.a` records the acceleration actually realised.
fn integrate_longitudinal(veh: &mut Vehicle, a: f64, dt: f64, v_max: Option<f64>) {
    let v0 = veh.v;
    let v1 = v0 + a * dt;
    if let Some(v_max) = v_max {
        // The jerk-limited controller already respects the bounds; clamp only rounding.
        let v1 = v1.clamp(0.0, v_max);
        veh.x += 0.5 * (v0 + v1) * dt;
        veh.v = v1;
        veh.a = a;
    } else if v1 < 0.0 {
        // Stops within the step: travel only the braking distance.
        veh.x += v0 * v0 / (2.0 * -a);
        veh.v = 0.0;
        veh.a = -v0 / dt;
    } else {
        veh.x += v0 * dt + 0.5 * a * dt * dt;
        veh.v = v1;
        veh.a = a;
    }
}

fn advance_lateral(veh: &mut Vehicle, road: &Road, dt: f64) {
    let y0 = veh.y;
    if let Some(mut lc) = veh.lane_change {
        lc.steps_elapsed += 1;
        veh.y = lc.y(dt);
        if lc.is_complete(dt) {
            veh.y = lc.to_y;
            veh.lane_change = None;
        } else {
            veh.lane_change = Some(lc);
        }
    }
    veh.vy = (veh.y - y0) / dt;
    veh.lane = road.lane_of(veh.y);
}
