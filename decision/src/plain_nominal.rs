//! How a nominal decision stands against the MPC as the paper writes it.
//!
//! The shipped nominal layer carries two relaxations the paper does not have: the violation
//! allowance (an SV already inside its margin may stay inside by a decaying share,
//! `idm.violation_decay` / `idm.violation_recovery_mps2`) and the soft band (the hysteresis
//! slack may reach down to the hard margin instead of stopping at `d_HS = d_rel - d_trig`,
//! `hysteresis.soft_band`). A nominal share measured with them is not the paper's NOR.
//! [`classify_nominal`] tells, for one nominal decision, whether the plain MPC (neither
//! relaxation) accepts the chosen plan, would have found another plan, or needed which
//! relaxation: the comparison with the paper counts only the first two (docs/formulation-notes.md).

use serde::{Deserialize, Serialize};

use crate::config::PlannerConfig;
use crate::enumeration;
use crate::evaluate::{evaluate, Mode};
use crate::problem::{prepare, Problem};
use crate::types::Action;
use crate::validate::ValidSituation;

/// Where a nominal decision stands against the plain MPC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NominalClass {
    /// The chosen plan satisfies the plain MPC's rows.
    Plain,
    /// The chosen plan uses a relaxation, but the plain MPC has a feasible plan too.
    RelaxedByChoice,
    /// Without the violation allowance the nominal problem has no plan.
    NeededAllowance,
    /// With the band slack bounded by `d_HS` the nominal problem has no plan.
    NeededSoftBand,
    /// Either relaxation alone suffices, but the plain MPC has no plan.
    NeededEither,
}

impl NominalClass {
    /// Whether the plain MPC is nominal here (the paper's NOR counts it).
    pub fn plain_feasible(self) -> bool {
        matches!(self, Self::Plain | Self::RelaxedByChoice)
    }
}

/// `config` without the violation allowance (`allowance`) and/or with the band slack bounded
/// by `d_HS` (`band`).
fn without(config: &PlannerConfig, allowance: bool, band: bool) -> PlannerConfig {
    let mut c = config.clone();
    if allowance {
        c.idm.violation_decay = 0.0;
        c.idm.violation_recovery_mps2 = 0.0;
        // Not a relaxation but not the paper's either: its margins are IDM's alone.
        c.idm.min_time_headway_s = 0.0;
    }
    if band {
        c.hysteresis.soft_band = false;
    }
    c
}

fn problem(config: &PlannerConfig, situation: &ValidSituation) -> Problem {
    prepare(config, situation.get()).problem
}

fn nominal_feasible(config: &PlannerConfig, situation: &ValidSituation) -> bool {
    enumeration::solve(&problem(config, situation), Mode::Nominal)
        .0
        .is_some()
}

/// The class of a nominal decision that chose `plan` (its actions) for `situation` under
/// `config`. Exact: the chosen plan is evaluated, and the plain problems are solved by
/// enumeration (meant for the campaign's horizons; the cost grows with the sequence count).
pub fn classify_nominal(config: &PlannerConfig, situation: &ValidSituation, plan: &[Action]) -> NominalClass {
    let plain = without(config, true, true);
    let plain_problem = problem(&plain, situation);
    if evaluate(&plain_problem, plan, Mode::Nominal).is_some() {
        return NominalClass::Plain;
    }
    if enumeration::solve(&plain_problem, Mode::Nominal).0.is_some() {
        return NominalClass::RelaxedByChoice;
    }
    let with_band_only = nominal_feasible(&without(config, true, false), situation);
    let with_allowance_only = nominal_feasible(&without(config, false, true), situation);
    match (with_band_only, with_allowance_only) {
        (true, true) => NominalClass::NeededEither,
        (true, false) => NominalClass::NeededSoftBand,
        (false, true) => NominalClass::NeededAllowance,
        // Each alone fails, only both together succeed: the band is the one the campaign
        // depends on more (docs/formulation-notes.md); both are needed.
        (false, false) => NominalClass::NeededEither,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{EgoState, Maneuver, PlannerMemory, Road, Situation, SvObservation};
    use crate::Planner;

    fn situation(gap_m: f64, sv_speed: f64) -> Situation {
        Situation {
            road: Road {
                lanes: 1,
                lane_width_m: 3.5,
                speed_limit_mps: 40.0,
            },
            ego: EgoState {
                x_m: 0.0,
                y_m: 0.0,
                v_mps: 25.0,
                desired_speed_mps: 30.0,
                maneuver: Maneuver { lane: 1, beta: 0 },
            },
            svs: vec![SvObservation::new(1, gap_m, 0.0, sv_speed, 0.0)],
            memory: PlannerMemory::default(),
        }
    }

    fn decide(config: &PlannerConfig, s: &Situation) -> (crate::Decision, ValidSituation) {
        let valid = ValidSituation::new(config, s).unwrap();
        let d = Planner::new(config.clone()).unwrap().decide_valid(&valid).unwrap();
        (d, valid)
    }

    #[test]
    fn a_free_road_is_plain_and_a_cut_in_close_ahead_needs_the_allowance() {
        let config = PlannerConfig::default();
        let (d, valid) = decide(&config, &situation(150.0, 30.0));
        assert_eq!(d.layer, crate::Layer::Nominal);
        let plan: Vec<Action> = d.plan.iter().map(|s| s.action).collect();
        assert_eq!(classify_nominal(&config, &valid, &plan), NominalClass::Plain);
        // An SV 12 m ahead at the ego's speed: inside the IDM margin (about 40 m) at once, so
        // the plain rows cannot hold within the horizon; the allowance makes it nominal.
        let (d, valid) = decide(&config, &situation(12.0, 25.0));
        assert_eq!(d.layer, crate::Layer::Nominal);
        let plan: Vec<Action> = d.plan.iter().map(|s| s.action).collect();
        let class = classify_nominal(&config, &valid, &plan);
        assert!(
            matches!(class, NominalClass::NeededAllowance | NominalClass::NeededEither),
            "{class:?}"
        );
        assert!(!class.plain_feasible());
        // Without the allowance the same state is not nominal: the classification agrees
        // with the planner run as the paper writes it.
        let plain = without(&config, true, true);
        let (d, _) = decide(&plain, &situation(12.0, 25.0));
        assert_ne!(d.layer, crate::Layer::Nominal);
    }
}
