use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::{Road, SimError, MAX_LANES, MIN_LANES, VEHICLE_LENGTH};

/// Initial state of one vehicle, at the centre of `lane`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VehicleInit {
    /// Longitudinal position of the centre (m).
    pub x: f64,
    /// Lane index, 1 = leftmost.
    pub lane: u8,
    /// Initial speed (m/s).
    pub v: f64,
    /// IDM desired speed (m/s).
    pub desired_speed: f64,
}

/// A traffic scene: road, ego and surrounding vehicles (SV `k` in `svs` gets id `k + 1`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// Road geometry and speed limit.
    pub road: Road,
    /// Ego initial state (id 0).
    pub ego: VehicleInit,
    /// Surrounding vehicles (ids 1..).
    pub svs: Vec<VehicleInit>,
}

impl Scenario {
    /// The deterministic scene of the paper's Table II (Case 1).
    pub fn case1() -> Self {
        let sv = |lane, x, v| VehicleInit {
            x,
            lane,
            v,
            desired_speed: v,
        };
        Scenario {
            road: Road {
                lanes: 2,
                lane_width: crate::LANE_WIDTH,
                speed_limit: 40.0,
            },
            ego: VehicleInit {
                x: 110.77,
                lane: 2,
                v: 16.15,
                desired_speed: 25.0,
            },
            svs: vec![
                sv(1, 277.93, 22.93),
                sv(2, 175.50, 24.54),
                sv(1, 74.75, 27.24),
                sv(1, 383.90, 23.51),
                sv(2, 300.51, 21.38),
            ],
        }
    }

    /// A randomized scene for the Monte-Carlo campaign (see [`TrafficConfig`]).
    ///
    /// The ego is placed first, then the SVs in id order; a vehicle that lands too close
    /// to an already placed one in its lane is redrawn entirely.
    pub fn random(cfg: &TrafficConfig, seed: u64) -> Result<Self, SimError> {
        cfg.validate()?;
        let (lo, hi) = cfg.speed_range;
        let road = Road::new(cfg.lanes, hi + cfg.speed_limit_margin)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut placed: Vec<VehicleInit> = Vec::with_capacity(cfg.sv_count as usize + 1);
        for id in 0..=cfg.sv_count {
            let mut attempt = 0;
            let vehicle = loop {
                if attempt == cfg.max_retries {
                    return Err(SimError::PlacementFailed {
                        vehicle: id,
                        retries: cfg.max_retries,
                    });
                }
                attempt += 1;
                let x = rng.random_range(cfg.x_range.0..=cfg.x_range.1);
                let lane = rng.random_range(1..=cfg.lanes);
                let v = rng.random_range(lo..=hi);
                // The ego wants the top of the range; SVs draw their own.
                let desired_speed = if id == 0 { hi } else { rng.random_range(lo..=hi) };
                let candidate = VehicleInit {
                    x,
                    lane,
                    v,
                    desired_speed,
                };
                if placed.iter().all(|o| cfg.spacing_ok(&candidate, o)) {
                    break candidate;
                }
            };
            placed.push(vehicle);
        }
        let ego = placed.remove(0);
        Ok(Scenario { road, ego, svs: placed })
    }
}

/// Parameters of a randomized scene (one row of the paper's Table I plus placement rules).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrafficConfig {
    /// Number of lanes, `2..=5`.
    pub lanes: u8,
    /// Number of surrounding vehicles.
    pub sv_count: u32,
    /// Initial and desired speeds are uniform in `[lo, hi]` (m/s).
    pub speed_range: (f64, f64),
    /// Initial positions are uniform in this interval (m).
    pub x_range: (f64, f64),
    /// Minimum initial bumper gap in a lane (m).
    pub min_gap: f64,
    /// Minimum initial time headway of the follower (s).
    pub min_headway: f64,
    /// Placement attempts per vehicle before giving up.
    pub max_retries: u32,
    /// Speed limit = top of the speed range + this margin (m/s).
    pub speed_limit_margin: f64,
}

impl Default for TrafficConfig {
    fn default() -> Self {
        TrafficConfig {
            lanes: 3,
            sv_count: 8,
            speed_range: (25.0, 40.0),
            x_range: (0.0, 500.0),
            min_gap: 10.0,
            min_headway: 1.0,
            max_retries: 1000,
            speed_limit_margin: 5.0,
        }
    }
}

/// One row of the paper's Table I.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PaperTableEntry {
    /// Configuration id, 1..=18.
    pub id: u8,
    /// Number of Monte-Carlo trials N.
    pub trials: u32,
    /// Scene parameters of the row.
    pub config: TrafficConfig,
}

impl TrafficConfig {
    /// A config with the default placement rules.
    pub fn new(lanes: u8, sv_count: u32, speed_range: (f64, f64)) -> Self {
        TrafficConfig {
            lanes,
            sv_count,
            speed_range,
            ..Self::default()
        }
    }

    /// The 18 configurations of the paper's Table I, in id order.
    pub fn paper_table() -> Vec<PaperTableEntry> {
        const TRIALS: [u32; 18] = [
            500, 375, 325, 325, 600, 375, 500, 350, 325, 425, 625, 525, 500, 325, 375, 425, 600, 575,
        ];
        let mut out = Vec::with_capacity(18);
        for lanes in [2u8, 3, 4] {
            for speed_range in [(10.0, 20.0), (25.0, 40.0)] {
                for sv_count in [5u32, 8, 10] {
                    let idx = out.len();
                    out.push(PaperTableEntry {
                        id: idx as u8 + 1,
                        trials: TRIALS[idx],
                        config: TrafficConfig::new(lanes, sv_count, speed_range),
                    });
                }
            }
        }
        out
    }

    /// Required initial bumper gap behind a leader for a follower at speed `v_follower`.
    pub fn required_gap(&self, v_follower: f64) -> f64 {
        self.min_gap.max(self.min_headway * v_follower)
    }

    /// Whether two initial vehicles respect the placement spacing rule.
    pub fn spacing_ok(&self, a: &VehicleInit, b: &VehicleInit) -> bool {
        if a.lane != b.lane {
            return true;
        }
        let follower = if a.x <= b.x { a } else { b };
        (a.x - b.x).abs() - VEHICLE_LENGTH >= self.required_gap(follower.v)
    }

    /// Rejects configurations that cannot produce a sensible scene.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(MIN_LANES..=MAX_LANES).contains(&self.lanes) {
            return Err(SimError::InvalidLaneCount(self.lanes));
        }
        let (lo, hi) = self.speed_range;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return Err(SimError::InvalidParameter {
                name: "speed_range",
                reason: "need 0 < lo <= hi",
            });
        }
        let (x0, x1) = self.x_range;
        if !(x0.is_finite() && x1.is_finite() && x0 <= x1) {
            return Err(SimError::InvalidParameter {
                name: "x_range",
                reason: "need finite start <= end",
            });
        }
        if !(self.min_gap.is_finite() && self.min_gap >= 0.0) {
            return Err(SimError::InvalidParameter {
                name: "min_gap",
                reason: "must be finite and non-negative",
            });
        }
        if !(self.min_headway.is_finite() && self.min_headway >= 0.0) {
            return Err(SimError::InvalidParameter {
                name: "min_headway",
                reason: "must be finite and non-negative",
            });
        }
        if !(self.speed_limit_margin.is_finite() && self.speed_limit_margin >= 0.0) {
            return Err(SimError::InvalidParameter {
                name: "speed_limit_margin",
                reason: "must be finite and non-negative",
            });
        }
        Ok(())
    }
}
