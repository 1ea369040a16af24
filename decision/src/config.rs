//! Every tunable of the planner in one serde struct, loadable from TOML.
//!
//! Defaults are the paper's Table III and the project's `formulation.md`; where this
//! project departs from them the field says why.

use serde::{Deserialize, Serialize};

use crate::error::ConfigError;

mod evidence;
mod solver;
mod validate;
pub use evidence::Evidence;
pub use solver::{Backend, HighsOptionValue, LpSolver, SolverSettings};

/// The complete planner configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct PlannerConfig {
    pub timing: Timing,
    pub vehicle: VehicleGeometry,
    pub ego: EgoModel,
    pub idm: IdmParams,
    pub prediction: Prediction,
    pub perception: Perception,
    pub hysteresis: Hysteresis,
    pub cost: CostWeights,
    pub recovery: Recovery,
    pub solver: SolverSettings,
}

/// Decision period and horizon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Timing {
    /// High-level period `T_h` in seconds.
    pub step_s: f64,
    /// Horizon `H` in steps.
    pub horizon: usize,
}

impl Default for Timing {
    fn default() -> Self {
        Self {
            step_s: 0.4,
            horizon: 3,
        }
    }
}

/// Vehicle body, shared by ego and SVs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleGeometry {
    pub length_m: f64,
    pub width_m: f64,
    /// A vehicle within this distance of a lane centre occupies that lane only; farther
    /// off-centre it occupies both lanes it lies between.
    pub lane_centre_tolerance_m: f64,
}

impl Default for VehicleGeometry {
    fn default() -> Self {
        Self {
            length_m: 5.0,
            width_m: 2.0,
            lane_centre_tolerance_m: 0.1,
        }
    }
}

/// The hybrid kinematic maps `f^sigma` and the action set, used for the ego and the SVs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EgoModel {
    /// Acceleration while decelerating (`beta = -1`), m/s^2: the fixed value of the discrete
    /// maps, and of the SVs' predicted braking branches.
    pub decel_mps2: f64,
    /// Acceleration while accelerating (`beta = +1`), m/s^2 (the largest one with
    /// `continuous_accel`).
    pub accel_mps2: f64,
    /// The paper's kinematic input `u_k`: the maneuver state fixes the sign of the ego's
    /// acceleration and the MPC picks its magnitude (`beta = -1`: `[max_decel, -cruise_band]`,
    /// `0`: `[-cruise_band, cruise_band]`, `+1`: `[cruise_band, accel]`). Off: each state has
    /// one fixed acceleration, as in formulation.md.
    pub continuous_accel: bool,
    /// Strongest braking the ego may plan, m/s^2 (with `continuous_accel`).
    pub max_decel_mps2: f64,
    /// Strongest braking the fallback commands, m/s^2: the vehicle's emergency braking, used
    /// only when an SV ahead needs more than the state's range of `beta = -1` to stay behind
    /// (Layer B's "front vehicle braking"); the MPC is then not asked. The MPC never plans
    /// it. Set it to what the vehicle can brake; at the range's lower end (`max_decel_mps2`,
    /// or `decel_mps2` without `continuous_accel`) the fallback brakes no harder than the MPC
    /// may. Without `continuous_accel` the range is the one deceleration, so below it any SV
    /// ahead that needs more than that deceleration is an emergency.
    pub emergency_decel_mps2: f64,
    /// Room Layer B's front case keeps for a front threat (an SV ahead the fallback brakes
    /// for) to slow down, m/s^2 (positive; 0: none): it brakes so that the ego could still
    /// stop behind that SV were it to brake this hard to a standstill from now. Braking just
    /// enough behind an SV at its present speed leaves none, and a fast approach to a slow
    /// vehicle ends in it when that vehicle slows down. Behind an SV at the ego's speed this
    /// never asks more than itself: at most the planned range (checked), so following is
    /// never an emergency, and at most the representative deceleration of `beta = -1` (the
    /// default) it changes nothing but a closing ego's braking.
    pub lead_brake_room_mps2: f64,
    /// Braking stronger than this is priced by `cost.w_hard_brake`, m/s^2.
    pub comfort_decel_mps2: f64,
    /// Braking stronger than this is priced by `cost.w_peak_brake` on top, m/s^2: with the
    /// linear price beyond `comfort_decel_mps2` alone, braking early moves every later
    /// position, so the LP's optimum puts all braking beyond the comfort level into the first
    /// step; priced beyond here too, it is spread over the horizon (docs/sumo.md, "Erratic
    /// drivers": fewer peaks, a little more time close to others; off by default).
    pub peak_decel_mps2: f64,
    /// Braking stronger than this is priced by `cost.w_firm_brake`, m/s^2: with a cost that
    /// grows faster than the braking, a gentle deceleration held longer beats a short hard
    /// one for the same loss of speed (a linear cost is indifferent and its LP optimum sits
    /// at the extremes, alternating cruise and hard braking).
    pub firm_decel_mps2: f64,
    /// `|a|` within this counts as cruising, m/s^2: the same dead band that reads an SV's
    /// `beta` from its acceleration.
    pub cruise_band_mps2: f64,
    /// Allow a lateral and a longitudinal change in the same step (9 actions instead of 5).
    pub combined_actions: bool,
    /// How long the vehicle takes for a one-lane change, s: how fast the evidence expects an
    /// SV changing lanes to move sideways.
    pub lane_change_s: f64,
    /// Which lanes a plan occupies after it changes lanes.
    pub plan_occupancy: PlanOccupancy,
}

/// Which lanes a plan occupies after a lane change: the rows of the SVs in those lanes apply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanOccupancy {
    /// Every lane the ego occupies now and every lane the plan has targeted, to the horizon's
    /// end: a lane change (3 s in the simulators) outlasts the horizon, and the body spans
    /// both lanes meanwhile (formulation.md).
    #[default]
    HeldThroughChange,
    /// The paper's `alpha`: after each step the ego is in the lane its maneuver targets and no
    /// other (eq:state_transition; the rows apply where an SV shares that lane), whether or not
    /// the plan changes lanes. A change is complete, for the rows, one step after it begins;
    /// during a change under way the lane the body is leaving no longer counts (its leader is
    /// released from the band, as the hysteresis follows the plan's lanes). The fallback still
    /// reckons with the body's lanes.
    TargetLane,
}

impl Default for EgoModel {
    fn default() -> Self {
        Self {
            decel_mps2: -3.0,
            accel_mps2: 1.5,
            continuous_accel: true,
            max_decel_mps2: -6.0,
            emergency_decel_mps2: -9.0,
            lead_brake_room_mps2: 3.0,
            comfort_decel_mps2: -2.0,
            peak_decel_mps2: -3.0,
            firm_decel_mps2: -1.0,
            cruise_band_mps2: 0.3,
            combined_actions: false,
            lane_change_s: 3.0,
            plan_occupancy: PlanOccupancy::HeldThroughChange,
        }
    }
}

/// Intelligent Driver Model parameters for the safety distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IdmParams {
    /// Jam distance `d0`, m.
    pub jam_distance_m: f64,
    /// Desired time headway `T`, s. The paper gives no value; 1.0 s is the IDM's highway
    /// value (formulation.md: 1.5; see docs/following-and-lane-choice.md).
    pub time_headway_s: f64,
    /// Maximum acceleration `a`, m/s^2.
    pub max_accel_mps2: f64,
    /// Comfortable deceleration `b`, m/s^2: the braking the dynamic term
    /// `v dv / (2 sqrt(a b))` budgets for matching a slower leader's speed. The paper gives no
    /// value; 3.0 is the ego's decelerating state (`ego.decel_mps2`; formulation.md: 2.0, see
    /// docs/following-and-lane-choice.md).
    pub comfort_decel_mps2: f64,
    /// The margin at step `h` follows the ego's predicted speed there (the IDM distance
    /// linearised at the measured speed) instead of staying at its value at the decision.
    pub speed_dependent: bool,
    /// An SV already inside its margin at the decision (it entered the perception window or
    /// cut in that close) may stay inside by this share of the violation, decaying by this
    /// factor per step (a discrete control-barrier condition); 0: the margin holds at once.
    pub violation_decay: f64,
    /// For an SV ahead, the violation may also stay as large as it would be if the ego braked
    /// at this deceleration (m/s^2, a magnitude) as soon as its maneuver state allows,
    /// whichever allows more: a deep violation (a cut-in close ahead) is then recovered by
    /// comfortable braking, not the strongest. The floor rows keep the decay alone. 0: the
    /// decay alone; with `violation_decay = 0` (the margin holds at once) it does nothing.
    pub violation_recovery_mps2: f64,
    /// Whose speeds size the distance to an SV behind the ego.
    pub rear_distance: RearDistance,
    /// The least time headway a margin asks for, s: the IDM distance never falls below
    /// `d0 + v_f * min_time_headway_s`, however much faster the leader (IDM's dynamic term
    /// alone lets a follower close to `d0` behind a leader pulling away). 0: off.
    pub min_time_headway_s: f64,
}

/// The IDM distance to an SV behind the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RearDistance {
    /// The SV follows the ego: `d_idm(v_sv, v_sv - v_ev)`, the distance the SV's own IDM
    /// keeps (formulation.md).
    SvFollows,
    /// The paper's literal form for every SV (its `d_idm` after eq:deterministic's
    /// definition): the ego's speed and `dv = v_ev - v_sv`, as if the ego followed.
    EgoSpeed,
}

impl Default for IdmParams {
    fn default() -> Self {
        Self {
            jam_distance_m: 2.0,
            time_headway_s: 1.0,
            max_accel_mps2: 1.5,
            comfort_decel_mps2: 3.0,
            speed_dependent: true,
            violation_decay: 0.8,
            violation_recovery_mps2: 1.5,
            rear_distance: RearDistance::SvFollows,
            min_time_headway_s: 0.6,
        }
    }
}

/// The SV scenario tree and its uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Prediction {
    /// Probability that an SV keeps its longitudinal maneuver in one step.
    pub p_keep_long: f64,
    /// Probability that an SV keeps its lane in one step.
    pub p_keep_lat: f64,
    /// Branches below this probability are pruned.
    pub p_min: f64,
    /// With a value above 0, a branch is also kept when it is at least this share as
    /// probable as the most probable one (see `scenario::keep_threshold`).
    pub p_min_relative: f64,
    /// At most this many branches are kept per SV (`K`).
    pub max_branches: usize,
    /// `|a|` below this is read as cruising when estimating an SV's `beta`, m/s^2.
    pub accel_dead_band_mps2: f64,
    /// Diagonal of the process noise `Q` on `[x, y, v]` per step (m^2, m^2, m^2/s^2).
    pub noise_diag: [f64; 3],
    /// Tail probability `epsilon` of the chance constraint.
    pub epsilon: f64,
    /// An SV moving sideways faster than this is predicted in the lane it moves towards
    /// from the first step (m/s); 0 switches this off.
    pub lateral_velocity_threshold_mps: f64,
    /// Where a laterally moving SV stops holding the lanes it occupies now once its
    /// extrapolated position reaches the next lane centre (docs/formulation-notes.md,
    /// "Lateral prediction").
    pub lateral_departure: LateralDeparture,
    /// A departure is extrapolated at this share of the measured lateral velocity: in the
    /// second half of a smooth lane change the lateral speed falls, and the constant-speed
    /// extrapolation puts the SV in the next lane 1.1-2.4 times sooner than it gets there.
    pub departure_speed_share: f64,
    /// The first step's transition probabilities from the SV's evidence (`evidence.rs`).
    pub evidence: Evidence,
    /// While a branch keeps the SV's measured longitudinal state it continues at the measured
    /// acceleration (stopping at zero speed), not at the state's representative one: a leader
    /// easing off at -1 m/s^2 is otherwise predicted at `ego.decel_mps2` (-3) in its most
    /// probable branch, the ego brakes for a deceleration that does not come, then cruises
    /// again when it sees so, and repeats. Off: every branch uses the representative
    /// accelerations, as in formulation.md.
    pub measured_accel_while_keeping: bool,
    /// The braking the ego needs to stay behind an SV braking behind a slower vehicle is
    /// reckoned with the SV braking down to that one's speed less `braking_end_margin_mps`,
    /// hedged against its braking on to a standstill (`braking_end.rs`). Off: every braking SV
    /// is taken to brake to a standstill.
    pub braking_ends_at_leader: bool,
    /// How far below the speed of the vehicle it brakes for an SV's braking may go, m/s.
    pub braking_end_margin_mps: f64,
}

impl Default for Prediction {
    fn default() -> Self {
        Self {
            p_keep_long: 0.8,
            p_keep_lat: 0.9,
            p_min: 0.15,
            p_min_relative: 0.3,
            max_branches: 4,
            accel_dead_band_mps2: 0.3,
            noise_diag: [0.25, 0.04, 0.25],
            epsilon: 0.05,
            lateral_velocity_threshold_mps: 0.0,
            lateral_departure: LateralDeparture::Always,
            departure_speed_share: 0.75,
            measured_accel_while_keeping: true,
            braking_ends_at_leader: true,
            braking_end_margin_mps: 2.0,
            evidence: Evidence::default(),
        }
    }
}

/// Perception window and input capacity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Perception {
    /// SVs farther ahead than this (centre to centre) are ignored, m.
    pub range_ahead_m: f64,
    /// SVs farther behind than this are ignored, m.
    pub range_behind_m: f64,
    /// The planner uses at most this many SVs of a request: the most relevant (nearest in
    /// travel time). A request may carry up to `MAX_INPUT_SVS`.
    pub max_svs: usize,
    /// Roads with more lanes than this are rejected.
    pub max_lanes: u8,
    /// A vehicle behind the ego in a lane the ego already occupies is responsible for its own
    /// gap: the ego gets no safety row for it there (it keeps one in every lane it moves
    /// into), so it is not asked to outrun a faster follower.
    pub rear_responsibility: bool,
}

impl Default for Perception {
    fn default() -> Self {
        Self {
            range_ahead_m: 200.0,
            range_behind_m: 100.0,
            max_svs: 16,
            max_lanes: 8,
            rear_responsibility: true,
        }
    }
}

/// Frozen-release hysteresis (paper III-D).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Hysteresis {
    /// Off: no corrective regime, every SV gets the plain chance constraint (Case 2 baseline).
    pub enabled: bool,
    /// The band's share of `d_idm`, `eps_trig = clamp(k_eps d_idm, eps_min, eps_max)`. The
    /// paper gives no value; 0.5 is formulation.md's (0.25 measured in
    /// docs/following-and-lane-choice.md).
    pub k_eps: f64,
    pub eps_min_m: f64,
    pub eps_max_m: f64,
    pub gamma1: f64,
    pub gamma2: f64,
    /// Let the hysteresis slack reach down to the hard safety margin `d_hc` instead of
    /// stopping at `d_HS = d_rel - d_trig`.
    ///
    /// With `d_HS` the corrective row demands `gap >= d_trig` at every step the moment it
    /// triggers — which is exactly when some predicted gap has fallen below `d_trig` — so
    /// the nominal problem is often infeasible on triggering and the fallback answers. The
    /// paper calls the band a buffer whose "strict enforcement is unnecessary" while safety
    /// rests on `d_hc`; with this on, the band is priced (`w_s` per metre) but never harder
    /// than `d_hc`. Measured on the campaign: see `docs/formulation-notes.md`.
    pub soft_band: bool,
    /// Release when the gaps reach the release distance on the rollout where the ego resumes
    /// accelerating (off: on the nominal rollout, as in the paper).
    pub release_on_resuming: bool,
    /// The frozen release distance shrinks to the one that holds at the leader's speed once
    /// the ego no longer closes in: a distance frozen at a high closing speed is otherwise
    /// kept long after the speeds matched, and the ego falls far behind.
    pub resize_release: bool,
    /// While the SV holds the ego below its desired speed (slower by more than 0.5 m/s) the
    /// ego is following it: reaching the release distance then does not release it.
    pub hold_while_following: bool,
    /// The band row asks for the release distance `anticipation_s` seconds ahead at today's
    /// relative speed: `gap + tau (v_sv - v_ego) >= d_rel`, s. An ego already falling back
    /// is not pushed to brake further, one still closing in is asked to brake early and
    /// gently, and the gap settles at the release distance instead of cycling around it
    /// (0: the paper's `gap >= d_rel`).
    pub anticipation_s: f64,
}

impl Default for Hysteresis {
    fn default() -> Self {
        Self {
            enabled: true,
            k_eps: 0.5,
            eps_min_m: 6.0,
            eps_max_m: 22.0,
            gamma1: 1.0,
            gamma2: 1.4,
            soft_band: true,
            release_on_resuming: true,
            resize_release: true,
            hold_while_following: true,
            anticipation_s: 2.0,
        }
    }
}

/// Objective weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CostWeights {
    /// `w_s`, per metre of hysteresis slack per step.
    pub w_slack: f64,
    /// `w_q`, per metre of global slack per step (Layer A).
    pub w_global: f64,
    /// `w_sigma` of a lane change, added to the longitudinal part.
    pub w_lane_change: f64,
    /// `w_sigma` of the next longitudinal state `[decelerate, cruise, accelerate]`, per step.
    ///
    /// `formulation.md` has `[2, 0, 1]`. The brake state's per-step price, beside a linear
    /// price on the braking itself, made the shortest brake the cheapest: the ego cruised at
    /// the band's edge (-0.3 m/s^2) and braked in short -2 m/s^2 kicks, two switches each.
    /// At 1 it follows a slowing leader in longer, gentler brakes: about 11 % fewer switches
    /// on both seeds (`docs/formulation-notes.md`). The accelerate state keeps its price: at
    /// 0 the ego is 0.9 m/s faster, but it also speeds up to each new leader (Case 2: three
    /// switches instead of one).
    pub w_beta: [f64; 3],
    /// Extra price of the state the plan ends in, `[decelerate, cruise, accelerate]`: a plan
    /// that ends braking or accelerating still owes the switch back to cruising, which lies
    /// beyond the horizon (a cost-to-go, like `w_speed_terminal`).
    pub w_beta_terminal: [f64; 3],
    /// `w_v`, per m/s of `|v_des - v_h|` per step.
    ///
    /// `formulation.md` suggests 0.5, but with `a_acc T_h = 0.6 m/s` one accelerating step
    /// gains at most `0.5 * 0.6 * 3 = 0.9`, less than its `w_beta[+1] = 1` there, so a slow
    /// ego would never speed up. At 1.0 a single accelerating step pays (`1.8 > 1`); see
    /// `docs/formulation-notes.md`.
    pub w_speed: f64,
    /// Extra weight on `|v_des - v_H|` at the horizon's end, per m/s: a speed deficit there
    /// persists beyond the horizon (a cost-to-go), which three steps of `w_speed` do not see.
    pub w_speed_terminal: f64,
    /// Terminal lane value, per m/s by which traffic ahead in the lane the plan ends in holds
    /// the ego below its desired speed.
    ///
    /// Not in the paper. A lane change takes 3 s and the horizon is 1.2 s, so within the
    /// horizon the ego still occupies its old lane and a change can never pay: without an
    /// estimate of what lies beyond the horizon the planner would never overtake.
    pub w_lane_speed: f64,
    /// How far ahead an SV counts as holding a lane's speed, m.
    pub lane_lookahead_m: f64,
    /// The time over which the lane value averages the speed a lane lets the ego hold, s: a
    /// slower SV ahead holds the lane at its own speed only from when the ego would reach it,
    /// so a far one weighs in gradually (0: at its full weight from any distance).
    pub lane_horizon_s: f64,
    /// Per m/s^2 of planned braking per step (with `ego.continuous_accel`).
    pub w_brake: f64,
    /// Per change of the longitudinal maneuver state (an action with `d_long != 0`): the
    /// paper's aim of few throttle / brake switches, priced on the switch itself.
    pub w_switch: f64,
    /// Per m/s^2 of planned braking beyond `ego.comfort_decel_mps2` per step.
    pub w_hard_brake: f64,
    /// Per m/s^2 of planned braking beyond `ego.firm_decel_mps2` per step.
    pub w_firm_brake: f64,
    /// Per m/s^2 of planned braking beyond `ego.peak_decel_mps2` per step (0: off, and the
    /// model has no column for it).
    pub w_peak_brake: f64,
}

impl Default for CostWeights {
    fn default() -> Self {
        Self {
            w_slack: 1.5,
            w_global: 1.0e4,
            w_lane_change: 4.0,
            w_beta: [1.0, 0.0, 1.0],
            w_beta_terminal: [0.0, 0.0, 0.0],
            w_speed: 1.0,
            w_speed_terminal: 4.0,
            w_lane_speed: 3.0,
            lane_lookahead_m: 200.0,
            lane_horizon_s: 60.0,
            w_brake: 1.0,
            w_switch: 4.0,
            w_hard_brake: 20.0,
            w_firm_brake: 2.0,
            w_peak_brake: 0.0,
        }
    }
}

/// Layer A bound.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Recovery {
    /// `gamma`: the global slack of a row is at most `gamma * d_idm`.
    pub gamma: f64,
}

impl Default for Recovery {
    fn default() -> Self {
        Self { gamma: 0.1 }
    }
}

/// Which rows see an SV that moves sideways leave the lanes it occupies now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LateralDeparture {
    /// None: the SV holds every lane it occupies now for the whole horizon.
    Never,
    /// The hysteresis trigger and band: an SV leaving the ego's lane is not followed any
    /// more once it is predicted in the next lane, while the hard rows keep it in the lane
    /// until the next decision sees it gone.
    Band,
    /// Every row, the hard ones too.
    #[default]
    Always,
}

impl PlannerConfig {
    /// Parse a TOML document; missing fields take their defaults.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let config: PlannerConfig = toml::from_str(text).map_err(|e| ConfigError::Parse(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// Render as TOML (used to write the documented defaults).
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).expect("config is always representable in TOML")
    }

    /// Standard-normal quantile `z_eps` for the configured `epsilon`.
    pub fn z_epsilon(&self) -> f64 {
        use statrs::distribution::{ContinuousCDF, Normal};
        Normal::standard().inverse_cdf(1.0 - self.prediction.epsilon)
    }
}
