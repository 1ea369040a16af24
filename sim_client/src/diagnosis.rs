//! What a decision the nominal MPC could not answer was in corrective mode for.
//!
//! The band row of an SV in corrective mode asks for its frozen trigger distance at every
//! step; how the SV came to be inside it says whether the ego could have avoided the
//! infeasibility. Used by the diagnose example (`SHOW_CAUSES=1`) over a whole campaign.

use std::fmt;

use crate::episode::DecisionRecord;

/// Decisions looked back over for how an SV came to be corrective: a lane change takes 3 s.
pub const LOOKBACK_DECISIONS: usize = 8;

/// How the SV a decision was corrective for came to be ahead inside its trigger distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum CauseClass {
    /// No SV was corrective: other rows (the rear rows, the adjacent lanes).
    NoCorrectiveSv,
    /// The ego changed its target lane shortly before the trigger.
    EgoLaneChange,
    /// The SV was beside the ego's lane shortly before the trigger.
    CutIn,
    /// The SV was not sent shortly before the trigger.
    CameIntoRange,
    /// The SV was ahead in the ego's lane all along: the ego closed in on it.
    ClosedIn,
}

/// The cause of one decision: the class and, for a corrective SV, the decisions since its trigger.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Cause {
    /// How the SV came to be inside its trigger distance.
    pub class: CauseClass,
    /// Decisions since that SV's trigger (0: this one); `None` without a corrective SV.
    pub decisions_since_trigger: Option<usize>,
}

impl fmt::Display for Cause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let class = match self.class {
            CauseClass::NoCorrectiveSv => "no SV corrective (other rows)",
            CauseClass::EgoLaneChange => "ego lane change",
            CauseClass::CutIn => "cut-in",
            CauseClass::CameIntoRange => "came into range",
            CauseClass::ClosedIn => "closed in",
        };
        match self.decisions_since_trigger {
            None => f.write_str(class),
            Some(0..=2) => write!(f, "{class}, trigger <= 0.8 s ago"),
            Some(3..=7) => write!(f, "{class}, trigger 1.2-2.8 s ago"),
            Some(_) => write!(f, "{class}, trigger >= 3.2 s ago"),
        }
    }
}

/// What decision `k` of one episode was in corrective mode for: of the SVs corrective after
/// it, the one triggered last (the longest unbroken run of decisions ending at `k` that keeps
/// it corrective starts at its trigger). Needs the decisions' requests
/// (`EpisodeSpec::record_trajectory`); `None` without them.
pub fn infeasibility_cause(d: &[DecisionRecord], k: usize) -> Option<Cause> {
    let request = |i: usize| d[i].request.as_ref();
    let half_lane = request(k)?.road.lane_width_m / 2.0;
    let lane_changed = |from: usize, to: usize| (from.max(1)..=to).any(|i| d[i].target_lane != d[i - 1].target_lane);
    let newest = d[k]
        .corrective_sv_ids
        .iter()
        .map(|id| {
            let mut start = k;
            while start > 0 && d[start - 1].corrective_sv_ids.contains(id) {
                start -= 1;
            }
            (start, *id)
        })
        .max();
    let Some((start, id)) = newest else {
        return Some(Cause {
            class: CauseClass::NoCorrectiveSv,
            decisions_since_trigger: None,
        });
    };
    let from = start.saturating_sub(LOOKBACK_DECISIONS);
    // Before the trigger: was the SV sent, and was it beside the ego's lane?
    let seen: Vec<Option<bool>> = (from..start)
        .filter_map(request)
        .map(|r| {
            r.svs
                .iter()
                .find(|sv| sv.id == id)
                .map(|sv| (sv.y_m - r.ego.y_m).abs() >= half_lane)
        })
        .collect();
    let class = if lane_changed(from, start) {
        CauseClass::EgoLaneChange
    } else if seen.contains(&Some(true)) {
        CauseClass::CutIn
    } else if seen.contains(&None) {
        CauseClass::CameIntoRange
    } else {
        CauseClass::ClosedIn
    };
    Some(Cause {
        class,
        decisions_since_trigger: Some(k - start),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use decision::{EgoState, Maneuver, PlannerMemory, Road, Situation, SvObservation};

    /// A decision at `index` with the ego in lane 2 (y = 3.5) or, with `ego_lane = 1`, lane 1
    /// (y = 7.0), one SV 40 m ahead at lateral position `sv_y` (none: not sent), and the
    /// corrective ids after it.
    fn record(index: u64, ego_lane: u8, sv_y: Option<f64>, corrective: &[u32]) -> DecisionRecord {
        let ego_y = if ego_lane == 1 { 7.0 } else { 3.5 };
        let situation = Situation {
            road: Road {
                lanes: 3,
                lane_width_m: 3.5,
                speed_limit_mps: 33.0,
            },
            ego: EgoState {
                x_m: 25.0 * index as f64,
                y_m: ego_y,
                v_mps: 25.0,
                desired_speed_mps: 30.0,
                maneuver: Maneuver {
                    lane: ego_lane,
                    beta: 0,
                },
            },
            svs: sv_y
                .map(|y| vec![SvObservation::new(9, 25.0 * index as f64 + 40.0, y, 22.0, 0.0)])
                .unwrap_or_default(),
            memory: PlannerMemory::default(),
        };
        DecisionRecord {
            index,
            time_s: 0.4 * index as f64,
            layer: Some(protocol::Layer::Fallback),
            target_lane: ego_lane,
            beta: 0,
            corrective_svs: corrective.len(),
            corrective_sv_ids: corrective.to_vec(),
            svs_sent: usize::from(sv_y.is_some()),
            ego_x_m: situation.ego.x_m,
            ego_y_m: ego_y,
            ego_speed_mps: 25.0,
            plan: Vec::new(),
            solve_us: 0,
            request: Some(protocol::PlanRequest::from_situation(1, index, 0, &situation).unwrap()),
            nominal_class: None,
        }
    }

    /// Decisions 0..=12: the SV at `sv_y(i)`, corrective from decision `trigger` on, the ego
    /// in `ego_lane(i)`.
    fn episode(
        sv_y: impl Fn(usize) -> Option<f64>,
        ego_lane: impl Fn(usize) -> u8,
        trigger: usize,
    ) -> Vec<DecisionRecord> {
        (0..=12)
            .map(|i| {
                let corrective: &[u32] = if i >= trigger { &[9] } else { &[] };
                record(i as u64, ego_lane(i), sv_y(i), corrective)
            })
            .collect()
    }

    fn cause(class: CauseClass, since: usize) -> Option<Cause> {
        Some(Cause {
            class,
            decisions_since_trigger: Some(since),
        })
    }

    #[test]
    fn an_sv_ahead_in_the_lane_all_along_was_closed_in_on() {
        let d = episode(|_| Some(3.5), |_| 2, 4);
        assert_eq!(infeasibility_cause(&d, 4), cause(CauseClass::ClosedIn, 0));
        assert_eq!(infeasibility_cause(&d, 12), cause(CauseClass::ClosedIn, 8));
        let label = |k| infeasibility_cause(&d, k).unwrap().to_string();
        assert_eq!(label(6), "closed in, trigger <= 0.8 s ago");
        assert_eq!(label(7), "closed in, trigger 1.2-2.8 s ago");
        assert_eq!(label(11), "closed in, trigger 1.2-2.8 s ago");
        assert_eq!(label(12), "closed in, trigger >= 3.2 s ago");
    }

    #[test]
    fn an_sv_from_the_next_lane_cut_in() {
        // In lane 1 (y = 7.0) until decision 3, then drifting into the ego's lane.
        let d = episode(|i| Some(if i <= 3 { 7.0 } else { 3.5 }), |_| 2, 6);
        assert_eq!(infeasibility_cause(&d, 7), cause(CauseClass::CutIn, 1));
        // Beside the lane only before the look-back: closed in after all.
        let d = episode(|i| Some(if i == 0 { 7.0 } else { 3.5 }), |_| 2, 10);
        assert_eq!(infeasibility_cause(&d, 10), cause(CauseClass::ClosedIn, 0));
    }

    #[test]
    fn the_egos_own_lane_change_comes_first() {
        // The ego moves from lane 1 into lane 2 at decision 4, behind the SV there.
        let d = episode(|_| Some(3.5), |i| if i < 4 { 1 } else { 2 }, 5);
        assert_eq!(infeasibility_cause(&d, 5), cause(CauseClass::EgoLaneChange, 0));
    }

    #[test]
    fn an_sv_not_sent_before_came_into_range() {
        let d = episode(|i| (i >= 4).then_some(3.5), |_| 2, 6);
        assert_eq!(infeasibility_cause(&d, 6), cause(CauseClass::CameIntoRange, 0));
    }

    #[test]
    fn without_a_corrective_sv_it_is_the_other_rows_and_without_requests_nothing() {
        let mut d = episode(|_| Some(3.5), |_| 2, 13);
        assert_eq!(
            infeasibility_cause(&d, 8),
            Some(Cause {
                class: CauseClass::NoCorrectiveSv,
                decisions_since_trigger: None
            })
        );
        d[8].request = None;
        assert_eq!(infeasibility_cause(&d, 8), None);
    }

    #[test]
    fn the_newest_of_two_corrective_svs_counts() {
        // SV 9 corrective from decision 2, SV 4 (cut in) from decision 9.
        let mut d = episode(|_| Some(3.5), |_| 2, 2);
        for (i, r) in d.iter_mut().enumerate().skip(9) {
            r.corrective_sv_ids = vec![4, 9];
            let mut s = r.request.as_ref().unwrap().to_situation();
            s.svs.push(SvObservation::new(4, s.ego.x_m + 20.0, 3.5, 20.0, 0.0));
            r.request = Some(protocol::PlanRequest::from_situation(1, i as u64, 0, &s).unwrap());
        }
        for (i, r) in d.iter_mut().enumerate().take(9).skip(5) {
            let mut s = r.request.as_ref().unwrap().to_situation();
            s.svs.push(SvObservation::new(4, s.ego.x_m + 25.0, 7.0, 20.0, 0.0));
            r.request = Some(protocol::PlanRequest::from_situation(1, i as u64, 0, &s).unwrap());
        }
        assert_eq!(infeasibility_cause(&d, 11), cause(CauseClass::CutIn, 2));
    }
}
