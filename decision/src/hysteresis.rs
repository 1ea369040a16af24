//! Frozen-release hysteresis refresh (paper III-D), per SV.

use crate::idm::Thresholds;
use crate::types::CorrectiveEntry;

/// New corrective state of one SV ahead in the ego's lane (`None` in both gaps when it no
/// longer is, which releases it).
///
/// `min_gap` is the smallest gap over the horizon between the SV's mean prediction (the paper's
/// `mu_Delta`, probability-weighted over its kept branches) and the ego's nominal rollout (keep
/// lane and `beta`); `min_gap_resuming` the same on the rollout where the ego resumes
/// accelerating.
///
/// Trigger when some nominal gap falls below the *current* trigger distance (thresholds are
/// frozen at that moment; a re-trigger keeps the original freeze). Release when every gap
/// reaches the *frozen* release distance even if the ego resumed accelerating: the slack
/// drives the gap to exactly the release distance, so releasing there (on the nominal
/// rollout) would let the speed term pull the ego straight back into the band — the
/// oscillation hysteresis is meant to remove. The regime is kept while the ego follows, as in
/// the paper's Case 1, until the gap is genuinely safe or the SV leaves the ego's lane.
///
/// `following`: the SV holds the ego below its desired speed, so the ego is following it: then
/// reaching the release distance does not release it (the band keeps the ego there, and a
/// release would only let the speed term pull it back in, a trigger-release cycle).
pub fn refresh(
    sv_id: u32,
    previous: Option<CorrectiveEntry>,
    min_gap: Option<f64>,
    min_gap_resuming: Option<f64>,
    current: Thresholds,
    following: bool,
) -> Option<CorrectiveEntry> {
    let gap = min_gap?;
    if gap < current.trigger {
        return Some(previous.unwrap_or(CorrectiveEntry {
            sv_id,
            release_m: current.release,
            trigger_m: current.trigger,
        }));
    }
    match previous {
        Some(frozen) if !following && min_gap_resuming.unwrap_or(gap) >= frozen.release_m => None,
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(trigger: f64, release: f64) -> Thresholds {
        Thresholds {
            band: release - trigger,
            trigger,
            release,
        }
    }

    #[test]
    fn triggers_below_the_trigger_distance_and_freezes() {
        let e = refresh(7, None, Some(29.0), Some(28.0), t(30.0, 36.0), false).unwrap();
        assert_eq!((e.sv_id, e.trigger_m, e.release_m), (7, 30.0, 36.0));
        // Still closer than the (now smaller) trigger: the freeze from the first trigger stays.
        let again = refresh(7, Some(e), Some(20.0), Some(19.0), t(25.0, 29.0), false).unwrap();
        assert_eq!(again, e);
    }

    #[test]
    fn does_not_trigger_at_or_above_the_trigger_distance() {
        assert_eq!(refresh(1, None, Some(30.0), Some(29.0), t(30.0, 36.0), false), None);
    }

    #[test]
    fn stays_corrective_inside_the_band() {
        let frozen = CorrectiveEntry {
            sv_id: 1,
            release_m: 36.0,
            trigger_m: 30.0,
        };
        // Above the current trigger but below the frozen release: keep.
        assert_eq!(
            refresh(1, Some(frozen), Some(33.0), Some(32.0), t(28.0, 31.0), false),
            Some(frozen)
        );
    }

    #[test]
    fn releases_against_the_frozen_distance_not_the_current_one() {
        let frozen = CorrectiveEntry {
            sv_id: 1,
            release_m: 36.0,
            trigger_m: 30.0,
        };
        // The ego slowed, so the current release (31) is below the gap (33): the frozen
        // release (36) still holds it in corrective mode.
        assert_eq!(
            refresh(1, Some(frozen), Some(33.0), Some(33.0), t(26.0, 31.0), false),
            Some(frozen)
        );
        assert_eq!(
            refresh(1, Some(frozen), Some(36.5), Some(36.0), t(26.0, 31.0), false),
            None
        );
    }

    #[test]
    fn holds_while_resuming_would_fall_back_into_the_band() {
        let frozen = CorrectiveEntry {
            sv_id: 1,
            release_m: 36.0,
            trigger_m: 30.0,
        };
        // Cruising keeps the gap at the release distance, but accelerating would dip below it.
        assert_eq!(
            refresh(1, Some(frozen), Some(36.0), Some(35.2), t(26.0, 31.0), false),
            Some(frozen)
        );
    }

    #[test]
    fn holds_while_following_a_slower_leader() {
        let frozen = CorrectiveEntry {
            sv_id: 1,
            release_m: 36.0,
            trigger_m: 30.0,
        };
        // Far beyond the release distance, but the SV still holds the ego back: kept.
        assert_eq!(
            refresh(1, Some(frozen), Some(50.0), Some(49.0), t(26.0, 31.0), true),
            Some(frozen)
        );
        // It leaves the ego's lane: released all the same.
        assert_eq!(refresh(1, Some(frozen), None, None, t(26.0, 31.0), true), None);
    }

    #[test]
    fn releases_when_no_longer_ahead_in_the_ego_lane() {
        let frozen = CorrectiveEntry {
            sv_id: 1,
            release_m: 36.0,
            trigger_m: 30.0,
        };
        assert_eq!(refresh(1, Some(frozen), None, None, t(30.0, 36.0), false), None);
    }
}
