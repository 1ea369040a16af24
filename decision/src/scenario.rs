//! SV prediction as a pruned scenario tree with Gaussian noise (paper III-B).

use nalgebra::{Matrix3, Vector3};

use crate::config::PlannerConfig;
use crate::evidence::FirstStep;
use crate::lanes::LaneSet;
use crate::model::{action_set, transition, Kinematics};
use crate::types::{Action, Beta, Maneuver};

/// One retained branch of an SV's tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    /// Probability after pruning and renormalisation.
    pub probability: f64,
    pub actions: Vec<Action>,
    pub maneuvers: Vec<Maneuver>,
    /// Mean position and speed after each step.
    pub x: Vec<f64>,
    pub v: Vec<f64>,
    /// Lanes occupied after each step.
    pub occupancy: Vec<LaneSet>,
}

/// `beta` of an SV read from its measured acceleration, with a dead band around zero.
pub fn beta_from_accel(a: f64, dead_band: f64) -> Beta {
    if a.abs() < dead_band {
        0
    } else if a > 0.0 {
        1
    } else {
        -1
    }
}

/// One-step probabilities of the admissible actions from `m`: lateral and longitudinal keep
/// probabilities, the remainder split evenly over the admissible neighbours, the product
/// restricted to the action set and renormalised. With `first`, the step's lane changes and
/// braking have the evidence's probabilities instead ([`crate::evidence`]).
pub fn action_probabilities(
    config: &PlannerConfig,
    m: Maneuver,
    lanes: u8,
    first: Option<&FirstStep>,
) -> Vec<(Action, Maneuver, f64)> {
    let p = &config.prediction;
    let lateral = |d: i8| match (d, first) {
        (-1, Some(f)) => f.left,
        (1, Some(f)) => f.right,
        (0, Some(f)) => 1.0 - f.left - f.right,
        (0, None) => p.p_keep_lat,
        _ => (1.0 - p.p_keep_lat) / 2.0,
    };
    let change = (1.0 - p.p_keep_long) / 2.0;
    let longitudinal = |d: i8| match (d, first) {
        (-1, Some(f)) => f.brake,
        (0, Some(f)) => 1.0 - f.brake - change,
        (0, None) => p.p_keep_long,
        _ => change,
    };
    let mut out: Vec<(Action, Maneuver, f64)> = action_set(config.ego.combined_actions)
        .iter()
        .filter_map(|&d| {
            transition(m, d, lanes).map(|next| (d, next, lateral(d.lateral) * longitudinal(d.longitudinal)))
        })
        .collect();
    let total: f64 = out.iter().map(|(_, _, w)| w).sum();
    if first.is_some() && total <= 0.0 {
        // The evidence is certain of an action the state does not admit (a change off the
        // road): the background probabilities decide.
        return action_probabilities(config, m, lanes, None);
    }
    for entry in &mut out {
        entry.2 /= total;
    }
    // Certain evidence leaves actions of probability zero: they are no branch.
    out.retain(|entry| entry.2 > 0.0);
    out
}

/// Roll the SV's HMDP over the horizon, prune branches below `p_min`, keep the `K` most
/// probable (ties in action-set order) and renormalise. The most probable branch is always
/// kept, so a prediction never vanishes.
pub fn predict_branches(
    config: &PlannerConfig,
    kin: &Kinematics,
    lanes: u8,
    start: Maneuver,
    x0: f64,
    v0: f64,
    occupancy0: LaneSet,
) -> Vec<Branch> {
    predict_branches_from(config, kin, lanes, start, (x0, v0, None), occupancy0, None)
}

/// [`predict_branches`] from a measured `(x, v, a)`: with `a` given, the branch steps that
/// keep the start's longitudinal state continue at `a` (stopping at zero speed); with
/// `first`, the first step follows the evidence.
pub fn predict_branches_from(
    config: &PlannerConfig,
    kin: &Kinematics,
    lanes: u8,
    start: Maneuver,
    (x0, v0, a0): (f64, f64, Option<f64>),
    occupancy0: LaneSet,
    first: Option<FirstStep>,
) -> Vec<Branch> {
    let horizon = config.timing.horizon;
    let mut current = Branch {
        probability: 1.0,
        actions: Vec::with_capacity(horizon),
        maneuvers: Vec::with_capacity(horizon),
        x: Vec::with_capacity(horizon),
        v: Vec::with_capacity(horizon),
        occupancy: Vec::with_capacity(horizon),
    };
    /// Depth-first over the HMDP's action sequences, skipping every partial sequence whose
    /// probability is already below the threshold (a branch's probability only falls as it
    /// grows). With `leaves`, every leaf at or above `search.floor` is collected in action-set
    /// order; without, `search.floor` rises to the most probable leaf seen, so the search
    /// ends holding the most probable leaf's probability.
    #[allow(clippy::too_many_arguments)]
    fn grow(
        config: &PlannerConfig,
        kin: &Kinematics,
        lanes: u8,
        m: Maneuver,
        x: f64,
        v: f64,
        occ: LaneSet,
        kept_accel: Option<f64>,
        left: usize,
        current: &mut Branch,
        search: &mut Search,
    ) {
        let first = if current.actions.is_empty() { search.first } else { None };
        if left == 0 {
            match &mut search.leaves {
                Some(leaves) => leaves.push(current.clone()),
                None => search.floor = search.floor.max(current.probability),
            }
            return;
        }
        for (d, next, p) in action_probabilities(config, m, lanes, first.as_ref()) {
            if current.probability * p < search.floor {
                continue;
            }
            // The measured acceleration holds until the branch changes the longitudinal state.
            let kept = kept_accel.filter(|_| d.longitudinal == 0);
            let (x1, v1) = match kept {
                Some(a) => step_to_standstill(kin.dt, x, v, a),
                None => kin.step(x, v, next.beta),
            };
            // An SV's speed never goes negative: a braking branch that would reverse is not a
            // physical outcome, so it is dropped like a clipped action.
            if v1 < 0.0 {
                continue;
            }
            let occ1 = occ.with(next.lane);
            let saved = current.probability;
            current.probability *= p;
            current.actions.push(d);
            current.maneuvers.push(next);
            current.x.push(x1);
            current.v.push(v1);
            current.occupancy.push(occ1);
            grow(config, kin, lanes, next, x1, v1, occ1, kept, left - 1, current, search);
            current.probability = saved;
            current.actions.pop();
            current.maneuvers.pop();
            current.x.pop();
            current.v.pop();
            current.occupancy.pop();
        }
    }
    // First the most probable leaf's probability, then every leaf that can be kept: at least
    // `p_min`, or the most probable one. Pruning keeps the enumeration's order, so the
    // result is the full tree's, without its `5^H` leaves per SV.
    let mut run = |search: &mut Search| {
        grow(
            config,
            kin,
            lanes,
            start,
            x0,
            v0,
            occupancy0,
            a0,
            horizon,
            &mut current,
            search,
        )
    };
    let mut most_probable = Search {
        floor: 0.0,
        leaves: None,
        first,
    };
    run(&mut most_probable);
    let best = most_probable.floor;
    let threshold = keep_threshold(config, best);
    let mut keepable = Search {
        floor: best.min(threshold),
        leaves: Some(Vec::new()),
        first,
    };
    run(&mut keepable);
    let mut leaves = keepable.leaves.unwrap_or_default();
    // Stable sort keeps action-set order among equal probabilities.
    leaves.sort_by(|a, b| b.probability.total_cmp(&a.probability));
    let mut kept: Vec<Branch> = leaves
        .iter()
        .enumerate()
        .filter(|(i, b)| *i == 0 || b.probability >= threshold)
        .map(|(_, b)| b.clone())
        .take(config.prediction.max_branches)
        .collect();
    let total: f64 = kept.iter().map(|b| b.probability).sum();
    for b in &mut kept {
        b.probability /= total;
    }
    kept
}

/// State of one pruned search of [`predict_branches_from`].
struct Search {
    /// Partial sequences below this probability are not followed.
    floor: f64,
    /// Where leaves are collected; `None` while searching for the most probable leaf.
    leaves: Option<Vec<Branch>>,
    /// The first step's evidence.
    first: Option<FirstStep>,
}

/// Leaves at or above this probability are kept (besides the most probable one, `best`):
/// `p_min`, or with `p_min_relative` the lower of `p_min` and that share of `best`. Every leaf
/// of a horizon shares the later steps' background factors, so the relative rule keeps the
/// branches the evidence makes likely at any horizon, where `p_min` alone keeps only the
/// most probable one beyond a few steps.
fn keep_threshold(config: &PlannerConfig, best: f64) -> f64 {
    let p = &config.prediction;
    if p.p_min_relative > 0.0 {
        p.p_min.min(p.p_min_relative * best)
    } else {
        p.p_min
    }
}

/// One step at constant acceleration `a`, or to a standstill within the step.
fn step_to_standstill(dt: f64, x: f64, v: f64, a: f64) -> (f64, f64) {
    if v + a * dt >= 0.0 {
        (x + v * dt + 0.5 * a * dt * dt, v + a * dt)
    } else {
        // Stops after v / |a|, having covered v^2 / (2 |a|).
        (x + v * v / (-2.0 * a), 0.0)
    }
}

/// Longitudinal variance `Sigma_Delta(h)` for `h = 1..=H`: `Sigma' = A Sigma A^T + Q` on
/// `[x, y, v]` from a known initial state. The maps differ only in their input, so every
/// branch shares the same covariance.
pub fn longitudinal_variances(config: &PlannerConfig) -> Vec<f64> {
    let dt = config.timing.step_s;
    let a = Matrix3::new(1.0, 0.0, dt, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    let q = Matrix3::from_diagonal(&Vector3::from(config.prediction.noise_diag));
    let mut sigma = Matrix3::zeros();
    (0..config.timing.horizon)
        .map(|_| {
            sigma = a * sigma * a.transpose() + q;
            sigma[(0, 0)]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kin() -> Kinematics {
        Kinematics {
            dt: 0.4,
            accel: [-3.0, 0.0, 1.5],
            bounds: [(-3.0, -3.0), (0.0, 0.0), (1.5, 1.5)],
        }
    }

    #[test]
    fn beta_dead_band() {
        assert_eq!(beta_from_accel(0.29, 0.3), 0);
        assert_eq!(beta_from_accel(-0.29, 0.3), 0);
        assert_eq!(beta_from_accel(0.31, 0.3), 1);
        assert_eq!(beta_from_accel(-1.0, 0.3), -1);
    }

    #[test]
    fn one_step_probabilities_by_hand() {
        let c = PlannerConfig::default();
        // Middle lane of 3, cruising: weights keep 0.9*0.8 = 0.72, left/right 0.05*0.8 = 0.04,
        // decel/accel 0.9*0.1 = 0.09; total 0.98.
        let probs = action_probabilities(&c, Maneuver { lane: 2, beta: 0 }, 3, None);
        assert_eq!(probs.len(), 5);
        assert!((probs[0].2 - 0.72 / 0.98).abs() < 1e-12);
        assert!((probs[1].2 - 0.04 / 0.98).abs() < 1e-12);
        assert!((probs[3].2 - 0.09 / 0.98).abs() < 1e-12);
        // Lane 1 of 2, accelerating: left and accelerate are clipped; keep 0.72, right 0.04,
        // decel 0.09; total 0.85.
        let probs = action_probabilities(&c, Maneuver { lane: 1, beta: 1 }, 2, None);
        assert_eq!(probs.len(), 3);
        assert!((probs[0].2 - 0.72 / 0.85).abs() < 1e-12);
        let sum: f64 = probs.iter().map(|p| p.2).sum();
        assert!((sum - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_kept_state_continues_at_the_measured_acceleration() {
        let mut c = PlannerConfig::default();
        c.prediction.p_min = 0.05;
        let k = kin();
        // Easing off at -1 m/s^2 (beta = -1): the keep branch continues at -1, not at the
        // representative -3; a branch that leaves the state uses the representative values.
        let b = predict_branches_from(
            &c,
            &k,
            3,
            Maneuver { lane: 2, beta: -1 },
            (0.0, 20.0, Some(-1.0)),
            LaneSet::single(2),
            None,
        );
        let keep = b.iter().find(|x| x.actions.iter().all(|a| *a == Action::KEEP)).unwrap();
        let dt = k.dt;
        for h in 0..3 {
            let t = (h + 1) as f64 * dt;
            assert!((keep.v[h] - (20.0 - t)).abs() < 1e-9, "{:?}", keep.v);
            assert!((keep.x[h] - (20.0 * t - 0.5 * t * t)).abs() < 1e-9, "{:?}", keep.x);
        }
        let cruise = b
            .iter()
            .find(|x| x.actions[0].longitudinal == 1 && x.actions[1..].iter().all(|a| *a == Action::KEEP))
            .unwrap();
        // Leaving the state at once: the cruise state's 0 from the first step.
        let v1 = 20.0 + k.accel_of(0) * dt;
        assert!(
            (cruise.v[0] - v1).abs() < 1e-9 && (cruise.v[2] - v1).abs() < 1e-9,
            "{:?}",
            cruise.v
        );
        // Off, the keep branch brakes at the state's representative deceleration.
        let plain = predict_branches(&c, &k, 3, Maneuver { lane: 2, beta: -1 }, 0.0, 20.0, LaneSet::single(2));
        assert!((plain[0].v[2] - (20.0 + 3.0 * dt * k.accel_of(-1))).abs() < 1e-9);
    }

    #[test]
    fn a_kept_braking_state_stops_at_zero_speed() {
        let (x, v) = step_to_standstill(0.4, 10.0, 1.0, -5.0);
        assert_eq!(v, 0.0);
        assert!((x - 10.1).abs() < 1e-12, "{x}");
    }

    #[test]
    fn pruning_by_hand() {
        let mut c = PlannerConfig::default();
        c.prediction.p_min = 0.05; // formulation.md's pruning (the default keeps only KKK)
                                   // Middle lane of 3, cruising. From beta = 0 the keep probability is 0.72/0.98; from
                                   // beta = +-1 one longitudinal option is clipped, so keep is 0.72/0.89. Leaves:
                                   // KKK = (0.72/0.98)^3 = 0.396590, DKK = AKK = (0.09/0.98)(0.72/0.89)^2 = 0.060104,
                                   // KDK = KAK = (0.72/0.98)(0.09/0.98)(0.72/0.89) = 0.054585,
                                   // KKD = (0.72/0.98)^2 (0.09/0.98) = 0.049573 < p_min. K = 4 keeps KKK, DKK, AKK, KDK
                                   // (ties in enumeration order).
        let b = predict_branches(
            &c,
            &kin(),
            3,
            Maneuver { lane: 2, beta: 0 },
            0.0,
            20.0,
            LaneSet::single(2),
        );
        let k = Action::KEEP;
        let d = Action {
            lateral: 0,
            longitudinal: -1,
        };
        let a = Action {
            lateral: 0,
            longitudinal: 1,
        };
        let got: Vec<Vec<Action>> = b.iter().map(|x| x.actions.clone()).collect();
        assert_eq!(got, vec![vec![k, k, k], vec![d, k, k], vec![a, k, k], vec![k, d, k]]);
        let total = 0.396_590 + 2.0 * 0.060_104 + 0.054_585;
        assert!((b[0].probability - 0.396_590 / total).abs() < 1e-5);
        assert!((b[3].probability - 0.054_585 / total).abs() < 1e-5);
        // The first deceleration branch: 3 m/s^2 from 20 m/s -> x = 8 - 0.24, 16.48 - 0.72...
        assert!((b[1].x[0] - 7.76).abs() < 1e-12);
        assert!((b[1].v[2] - 16.4).abs() < 1e-12);
        // Lane 1 of 2, accelerating: keep = 0.72/0.85 = 0.84706 per step, so keep^3 = 0.60776,
        // and a deceleration at the last step = 0.84706^2 * 0.09/0.85 = 0.07597 >= p_min.
        let b = predict_branches(
            &c,
            &kin(),
            2,
            Maneuver { lane: 1, beta: 1 },
            0.0,
            20.0,
            LaneSet::single(1),
        );
        let raw_keep = (0.72f64 / 0.85).powi(3);
        let raw_dev = (0.72f64 / 0.85).powi(2) * 0.09 / 0.85;
        assert!(b.len() >= 2);
        assert!((b[0].probability / b[1].probability - raw_keep / raw_dev).abs() < 1e-9);
        assert!(b.len() <= c.prediction.max_branches);
        let total: f64 = b.iter().map(|x| x.probability).sum();
        assert!((total - 1.0).abs() < 1e-12);
    }

    #[test]
    fn at_most_k_branches() {
        let mut c = PlannerConfig::default();
        c.prediction.p_min = 0.0;
        c.prediction.max_branches = 4;
        let b = predict_branches(
            &c,
            &kin(),
            3,
            Maneuver { lane: 2, beta: 0 },
            0.0,
            20.0,
            LaneSet::single(2),
        );
        assert_eq!(b.len(), 4);
        assert!(b.windows(2).all(|w| w[0].probability >= w[1].probability));
    }

    #[test]
    fn covariance_grows_by_hand() {
        let c = PlannerConfig::default();
        let s = longitudinal_variances(&c);
        // h=1: q_x = 0.25. h=2: 0.25 + dt^2 q_v + 0.25 = 0.5 + 0.16*0.25 = 0.54.
        // h=3: Sxx2 + 2 dt Sxv2 + dt^2 Svv2 + q_x with Sxv2 = dt q_v = 0.1, Svv2 = 0.5:
        // 0.54 + 0.08 + 0.08 + 0.25 = 0.95.
        assert!((s[0] - 0.25).abs() < 1e-12);
        assert!((s[1] - 0.54).abs() < 1e-12);
        assert!((s[2] - 0.95).abs() < 1e-12);
    }

    #[test]
    fn braking_branches_never_reverse() {
        let mut c = PlannerConfig::default();
        c.prediction.p_min = 0.0;
        c.prediction.max_branches = 100;
        let b = predict_branches(
            &c,
            &kin(),
            2,
            Maneuver { lane: 1, beta: -1 },
            0.0,
            1.0,
            LaneSet::single(1),
        );
        assert!(b.iter().all(|br| br.v.iter().all(|&v| v >= 0.0)));
    }

    /// The unpruned tree, sorted, filtered and renormalised: the definition the pruned
    /// search must reproduce exactly.
    fn full_tree(
        c: &PlannerConfig,
        k: &Kinematics,
        lanes: u8,
        start: Maneuver,
        s0: (f64, f64, Option<f64>),
    ) -> Vec<Branch> {
        let mut leaves = Vec::new();
        let mut stack = vec![(
            Branch {
                probability: 1.0,
                actions: vec![],
                maneuvers: vec![],
                x: vec![],
                v: vec![],
                occupancy: vec![],
            },
            start,
            s0.0,
            s0.1,
            s0.2,
            LaneSet::single(start.lane),
        )];
        // Depth-first in action-set order: push children in reverse.
        while let Some((b, m, x, v, a, occ)) = stack.pop() {
            if b.actions.len() == c.timing.horizon {
                leaves.push(b);
                continue;
            }
            let mut children = Vec::new();
            for (d, next, p) in action_probabilities(c, m, lanes, None) {
                let kept = a.filter(|_| d.longitudinal == 0);
                let (x1, v1) = match kept {
                    Some(a) => step_to_standstill(k.dt, x, v, a),
                    None => k.step(x, v, next.beta),
                };
                if v1 < 0.0 {
                    continue;
                }
                let mut child = b.clone();
                child.probability *= p;
                child.actions.push(d);
                child.maneuvers.push(next);
                child.x.push(x1);
                child.v.push(v1);
                child.occupancy.push(occ.with(next.lane));
                children.push((child, next, x1, v1, kept, occ.with(next.lane)));
            }
            stack.extend(children.into_iter().rev());
        }
        leaves.sort_by(|a, b| b.probability.total_cmp(&a.probability));
        let mut kept: Vec<Branch> = leaves
            .into_iter()
            .enumerate()
            .filter(|(i, b)| *i == 0 || b.probability >= c.prediction.p_min)
            .map(|(_, b)| b)
            .take(c.prediction.max_branches)
            .collect();
        let total: f64 = kept.iter().map(|b| b.probability).sum();
        for b in &mut kept {
            b.probability /= total;
        }
        kept
    }

    #[test]
    fn the_pruned_search_keeps_exactly_the_full_trees_branches() {
        let k = kin();
        let mut compared = 0;
        for horizon in 1..=5 {
            for p_min in [0.0, 0.05, 0.15, 0.6] {
                for max_branches in [1, 4, 9] {
                    let mut c = PlannerConfig::default();
                    c.timing.horizon = horizon;
                    c.prediction.p_min = p_min;
                    c.prediction.max_branches = max_branches;
                    for lanes in 1..=3u8 {
                        for lane in 1..=lanes {
                            for beta in -1..=1 {
                                for s0 in [(0.0, 20.0, None), (5.0, 0.5, Some(-1.0)), (0.0, 12.0, Some(0.4))] {
                                    let start = Maneuver { lane, beta };
                                    let occ = LaneSet::single(lane);
                                    let pruned = predict_branches_from(&c, &k, lanes, start, s0, occ, None);
                                    assert_eq!(
                                        pruned,
                                        full_tree(&c, &k, lanes, start, s0),
                                        "H {horizon} p_min {p_min} K {max_branches} lanes {lanes} {start:?} {s0:?}"
                                    );
                                    compared += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
        assert!(compared > 1000, "{compared}");
    }
}
