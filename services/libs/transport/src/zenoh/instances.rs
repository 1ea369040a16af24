//! Several planner instances on one Zenoh network: their names and keys, the live set a
//! client keeps from their liveliness tokens, and the client's choice of an instance per
//! vehicle (rendezvous hashing, so that a vehicle stays with one instance and only the
//! vehicles of an instance that goes away move).

use std::collections::{BTreeSet, HashMap};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use ::zenoh::pubsub::Subscriber;
use ::zenoh::sample::{Sample, SampleKind};
use ::zenoh::{Session, Wait};
use protocol::{ZENOH_ALIVE_KEYS, ZENOH_PLAN_KEY};
use thiserror::Error;

/// An instance id that cannot be a Zenoh key chunk.
#[derive(Debug, Error, PartialEq, Eq)]
#[error("instance id {0:?}: 1 to 64 characters of A-Z a-z 0-9 . _ -")]
pub struct BadInstanceId(pub String);

/// Checks an instance id: it becomes one chunk of two key expressions, so no `/`, no
/// wildcard and no verbatim (`@`) chunk.
pub fn check_instance_id(id: &str) -> Result<(), BadInstanceId> {
    let ok = !id.is_empty()
        && id.len() <= 64
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'));
    ok.then_some(()).ok_or_else(|| BadInstanceId(id.to_owned()))
}

/// The default instance id: host name and process id (unique per running process, and
/// readable in logs), reduced to the characters [`check_instance_id`] allows.
pub fn default_instance_id() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    let host: String = host
        .trim()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' })
        .take(40)
        .collect();
    let host = if host.is_empty() { "planner".to_owned() } else { host };
    format!("{host}-{}", std::process::id())
}

/// The key of instance `id`'s own queryable.
pub fn instance_plan_key(id: &str) -> String {
    format!("{ZENOH_PLAN_KEY}/{id}")
}

/// The key of instance `id`'s liveliness token.
pub fn alive_key(id: &str) -> String {
    format!("{}/{id}", ZENOH_ALIVE_KEYS.trim_end_matches("/*"))
}

/// The instance id in a liveliness token's key, if it is one of ours.
pub fn instance_of_alive_key(key: &str) -> Option<&str> {
    let id = key.strip_prefix(ZENOH_ALIVE_KEYS.trim_end_matches('*'))?;
    check_instance_id(id).ok().map(|()| id)
}

/// Rendezvous (highest random weight) score of `instance` for `vehicle_id`: stable across
/// processes, platforms and releases (FNV-1a and SplitMix64, not `std`'s hasher).
pub fn rendezvous_score(vehicle_id: u64, instance: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in instance.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    let mut z = h ^ vehicle_id.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// `instances` in the order a vehicle tries them: highest score first (ties by name).
pub fn rendezvous_order<'a>(vehicle_id: u64, instances: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let mut ranked: Vec<(u64, &str)> = instances
        .into_iter()
        .map(|i| (rendezvous_score(vehicle_id, i), i))
        .collect();
    ranked.sort_unstable_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(b.1)));
    ranked.into_iter().map(|(_, i)| i.to_owned()).collect()
}

#[derive(Debug, Default)]
struct State {
    live: BTreeSet<String>,
    /// Instances that left a query unanswered, until when they are tried last.
    suspect: HashMap<String, Instant>,
}

/// The planner instances a client knows to be alive (shared with the liveliness
/// subscriber's callback), and those it suspects of hanging.
#[derive(Debug, Clone, Default)]
pub struct Instances(Arc<Mutex<State>>);

impl Instances {
    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Instance `id` declared its token.
    pub fn alive(&self, id: &str) {
        let mut s = self.state();
        // A token declared anew (a restart, a reconnection after its lease expired) wipes
        // the suspicion: the instance is worth trying again.
        s.suspect.remove(id);
        s.live.insert(id.to_owned());
    }

    /// Instance `id`'s token is gone (undeclared, or its session's lease expired).
    pub fn gone(&self, id: &str) {
        let mut s = self.state();
        s.live.remove(id);
        s.suspect.remove(id);
    }

    /// Instance `id` left a query unanswered: try it last until `until`.
    pub fn suspect(&self, id: &str, until: Instant) {
        self.state().suspect.insert(id.to_owned(), until);
    }

    /// The live instances, by name.
    pub fn live(&self) -> Vec<String> {
        self.state().live.iter().cloned().collect()
    }

    /// The live instances in the order `vehicle_id` tries them at `now`: rendezvous order,
    /// instances suspected at `now` moved to the end (in their rendezvous order).
    pub fn order(&self, vehicle_id: u64, now: Instant) -> Vec<String> {
        let mut s = self.state();
        s.suspect.retain(|_, until| *until > now);
        let mut order = rendezvous_order(vehicle_id, s.live.iter().map(String::as_str));
        order.sort_by_key(|id| s.suspect.contains_key(id));
        order
    }
}

/// Follows the planner instances' liveliness tokens on `session`, those present now
/// included (history); the subscriber keeps the returned set up to date until dropped.
pub fn follow(session: &Session) -> Result<(Instances, Subscriber<()>), super::Cause> {
    let instances = Instances::default();
    let tracked = instances.clone();
    let subscriber = session
        .liveliness()
        .declare_subscriber(ZENOH_ALIVE_KEYS)
        .history(true)
        .callback(move |sample: Sample| {
            if let Some(id) = instance_of_alive_key(sample.key_expr().as_str()) {
                tracing::debug!(instance = id, kind = %sample.kind(), "planner instance");
                match sample.kind() {
                    SampleKind::Put => tracked.alive(id),
                    SampleKind::Delete => tracked.gone(id),
                }
            }
        })
        .wait()?;
    Ok((instances, subscriber))
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn instance_ids_are_single_plain_chunks() {
        assert!(check_instance_id("planner-1.host_a").is_ok());
        for bad in ["", "a/b", "*", "@x", "a b", "$x", &"x".repeat(65)] {
            assert_eq!(check_instance_id(bad), Err(BadInstanceId(bad.to_owned())), "{bad:?}");
        }
        assert!(
            check_instance_id(&default_instance_id()).is_ok(),
            "{}",
            default_instance_id()
        );
        assert_eq!(instance_plan_key("a"), "hmdp/planner/plan/a");
        assert_eq!(alive_key("a"), "hmdp/planner/alive/a");
        assert_eq!(instance_of_alive_key("hmdp/planner/alive/a"), Some("a"));
        assert_eq!(instance_of_alive_key("hmdp/planner/stats"), None);
    }

    #[test]
    fn rendezvous_spreads_vehicles_evenly_and_moves_only_the_lost_instances_vehicles() {
        let three = ["host-a-101", "host-b-202", "host-c-303"];
        let first = |v, set: &[&str]| rendezvous_order(v, set.iter().copied())[0].clone();
        let mut counts = HashMap::new();
        for v in 0..3000u64 {
            *counts.entry(first(v, &three)).or_insert(0) += 1;
            // One instance leaves: only its vehicles move, to their second choice.
            let before = rendezvous_order(v, three);
            let after = first(v, &three[1..]);
            if before[0] == three[0] {
                assert_eq!(after, before[1]);
            } else {
                assert_eq!(after, before[0]);
            }
        }
        for (instance, n) in &counts {
            assert!((900..=1100).contains(n), "{instance}: {n} of 3000 vehicles");
        }
    }

    #[test]
    fn suspects_go_last_until_their_time_is_up_or_their_token_is_new() {
        let instances = Instances::default();
        for id in ["a", "b", "c"] {
            instances.alive(id);
        }
        let now = Instant::now();
        let order = instances.order(7, now);
        assert_eq!(order.len(), 3);
        instances.suspect(&order[0], now + Duration::from_secs(1));
        let suspected = instances.order(7, now);
        assert_eq!(suspected, [order[1].as_str(), &order[2], &order[0]]);
        assert_eq!(instances.order(7, now + Duration::from_secs(2)), order);
        instances.suspect(&order[0], now + Duration::from_secs(1));
        instances.alive(&order[0]);
        assert_eq!(instances.order(7, now), order);
        instances.gone(&order[0]);
        assert_eq!(instances.order(7, now), [order[1].as_str(), &order[2]]);
    }
}
