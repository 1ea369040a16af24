//! A closed loop on one lane for the integration tests: the planner decides every 0.4 s, the
//! ego applies each answer's set-point until the next, and all vehicles are integrated at
//! 50 ms. Each vehicle ahead is observed with the acceleration it had in the step before.
//! `run_jerk_limited` lets the ego's brakes build up at a given jerk instead of at once.

// Each test crate uses its own part of the loop.
#![allow(dead_code)]

use decision::{EgoState, Layer, Maneuver, Planner, PlannerConfig, PlannerMemory, Road, Situation, SvObservation};

pub const LENGTH_M: f64 = 5.0;
const DT_S: f64 = 0.05;
const STEPS_PER_DECISION: u32 = 8;

/// A vehicle ahead of the ego in its lane: where it starts, and its acceleration as a function
/// of time and its own speed, the speed kept within `speed_bounds` after each step.
pub struct Vehicle {
    pub x_m: f64,
    pub v_mps: f64,
    pub accel: Box<dyn Fn(f64, f64) -> f64>,
    pub speed_bounds: (f64, f64),
}

impl Vehicle {
    /// A vehicle holding its speed.
    pub fn steady(x_m: f64, v_mps: f64) -> Vehicle {
        Vehicle {
            x_m,
            v_mps,
            accel: Box::new(|_, _| 0.0),
            speed_bounds: (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
}

/// The road, the ego and the vehicles ahead of it (the first one is the ego's leader), all on
/// the lane at y = 0, the road's lane `lanes`.
pub struct ClosedLoop {
    pub config: PlannerConfig,
    pub lanes: u8,
    pub desired_speed_mps: f64,
    pub ego_v_mps: f64,
    pub vehicles: Vec<Vehicle>,
    pub duration_s: f64,
}

/// One decision: the bumper gap to the leader then, its set-point and its layer.
pub struct Decided {
    pub gap_m: f64,
    pub accel_mps2: f64,
    pub layer: Layer,
}

/// What a [`ClosedLoop`] gives.
pub struct Trace {
    pub decisions: Vec<Decided>,
    /// The least bumper gap to the leader over every step.
    pub least_gap_m: f64,
    pub ego_x_m: f64,
    pub ego_v_mps: f64,
    pub final_gap_m: f64,
}

impl Trace {
    /// The ego's strongest planned braking (m/s^2, <= 0).
    pub fn strongest_braking(&self) -> f64 {
        self.decisions.iter().map(|d| d.accel_mps2).fold(0.0, f64::min)
    }
}

impl ClosedLoop {
    pub fn run(self) -> Trace {
        self.run_jerk_limited(f64::INFINITY)
    }

    /// [`ClosedLoop::run`] with the ego's acceleration moving towards each set-point by at most
    /// `jerk_mps3` per second, as a vehicle's brakes build up.
    pub fn run_jerk_limited(self, jerk_mps3: f64) -> Trace {
        let mut planner = Planner::new(self.config).unwrap();
        let lane = self.lanes;
        let mut vehicles = self.vehicles;
        let mut accels = vec![0.0; vehicles.len()];
        let (mut x_ego, mut v_ego) = (0.0, self.ego_v_mps);
        let (mut memory, mut beta, mut accel) = (PlannerMemory::default(), 0, 0.0);
        let mut applied = 0.0_f64;
        let gap = |x_ego: f64, vehicles: &[Vehicle]| vehicles[0].x_m - x_ego - LENGTH_M;
        let mut trace = Trace {
            decisions: Vec::new(),
            least_gap_m: f64::INFINITY,
            ego_x_m: 0.0,
            ego_v_mps: 0.0,
            final_gap_m: 0.0,
        };
        let steps = (self.duration_s / DT_S).round() as u32;
        for step in 0..steps {
            if step % STEPS_PER_DECISION == 0 {
                let s = Situation {
                    road: Road {
                        lanes: self.lanes,
                        lane_width_m: 3.5,
                        speed_limit_mps: 33.33,
                    },
                    ego: EgoState {
                        x_m: x_ego,
                        y_m: 0.0,
                        v_mps: v_ego,
                        desired_speed_mps: self.desired_speed_mps,
                        maneuver: Maneuver { lane, beta },
                    },
                    svs: vehicles
                        .iter()
                        .zip(&accels)
                        .zip(1..)
                        .map(|((v, &a), id)| SvObservation::new(id, v.x_m, 0.0, v.v_mps, a))
                        .collect(),
                    memory: memory.clone(),
                };
                let d = planner.decide(&s).unwrap();
                (memory, beta, accel) = (d.memory, d.next_maneuver.beta, d.setpoint.accel_mps2);
                trace.decisions.push(Decided {
                    gap_m: gap(x_ego, &vehicles),
                    accel_mps2: accel,
                    layer: d.layer,
                });
            }
            let t = f64::from(step) * DT_S;
            for (v, a) in vehicles.iter_mut().zip(accels.iter_mut()) {
                *a = (v.accel)(t, v.v_mps);
                v.v_mps = (v.v_mps + *a * DT_S).clamp(v.speed_bounds.0, v.speed_bounds.1);
                v.x_m += v.v_mps * DT_S;
            }
            let ramp = jerk_mps3 * DT_S;
            applied = accel.clamp(applied - ramp, applied + ramp);
            v_ego = (v_ego + applied * DT_S).max(0.0);
            x_ego += v_ego * DT_S;
            trace.least_gap_m = trace.least_gap_m.min(gap(x_ego, &vehicles));
        }
        trace.ego_x_m = x_ego;
        trace.ego_v_mps = v_ego;
        trace.final_gap_m = gap(x_ego, &vehicles);
        trace
    }
}
