"""The planner instances a client sees and the one it asks for each vehicle (docs/deploy.md,
"Scaling out"): liveliness tokens, rendezvous hashing bit for bit as the Rust channel's, and
suspicion of an instance that left a request unanswered. Part of hmdp_client's API."""

import re
import threading
import time

import zenoh

ALIVE_KEYS = "hmdp/planner/alive/*"  # the instances' liveliness tokens (protocol::names)
# An instance id: one plain key chunk (transport::zenoh::instances::check_instance_id).
INSTANCE_ID = re.compile(r"[A-Za-z0-9._-]{1,64}\Z")
# Failover between instances (transport::zenoh::Failover's defaults): without a valid answer
# this long after sending, the request goes once to the next instance, and the silent one is
# tried last for SUSPECT_FOR_S.
RETRY_AFTER_S = 0.15
SUSPECT_FOR_S = 2.0


_MASK64 = (1 << 64) - 1


def rendezvous_score(vehicle_id, instance):
    """Rendezvous (highest random weight) score of `instance` for `vehicle_id`: FNV-1a of the
    instance id mixed with the vehicle id by SplitMix64, bit for bit the Rust channel's
    (transport::zenoh::instances::rendezvous_score), so that both pick the same instance."""
    h = 0xCBF29CE484222325
    for b in instance.encode():
        h = ((h ^ b) * 0x100000001B3) & _MASK64
    z = h ^ ((vehicle_id * 0x9E3779B97F4A7C15) & _MASK64)
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return z ^ (z >> 31)


def rendezvous_order(vehicle_id, instances):
    """`instances` in the order a vehicle tries them: highest score first, ties by name."""
    ranked = sorted((-rendezvous_score(vehicle_id, i), i) for i in instances)
    return [i for _, i in ranked]


def instance_of_alive_key(key):
    """The instance id in a liveliness token's key, or None if it is not one of ours."""
    prefix = ALIVE_KEYS[:-1]
    if not key.startswith(prefix):
        return None
    instance = key[len(prefix) :]
    return instance if INSTANCE_ID.match(instance) else None


class Instances:
    """The planner instances whose liveliness tokens this session sees, those suspected of
    hanging, and the choice of an instance per vehicle (with one retry on the next; see
    `ask`). `last_instance` / `last_retries`: who answered the last request, and how often it
    was sent again."""

    def __init__(self, session, retry_after_s=RETRY_AFTER_S, suspect_for_s=SUSPECT_FOR_S):
        self.retry_after_s = retry_after_s
        self.suspect_for_s = suspect_for_s
        self.last_instance = None
        self.last_retries = 0
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._events = 0  # tokens seen (declared or gone), to tell when the history is in
        self._live = set()
        self._suspect = {}  # instance -> time.monotonic() until which it is tried last
        self.subscriber = session.liveliness().declare_subscriber(ALIVE_KEYS, self._on_token, history=True)
        self._await_history()

    def _await_history(self, first_s=0.5, quiet_s=0.05):
        """Waits for the tokens present now, before the first request: the subscriber's
        history arrives asynchronously (a few ms after the declaration, all at once; a
        liveliness get through hmdp-router returned no token). Up to `first_s` for a first
        token (a planner without instances has none), then until none came for `quiet_s`."""
        give_up = time.monotonic() + first_s
        with self._changed:
            while self._events == 0 and time.monotonic() < give_up:
                self._changed.wait(give_up - time.monotonic())
            seen = -1
            while self._events and seen != self._events:
                seen = self._events
                self._changed.wait(quiet_s)

    def _on_token(self, sample):
        instance = instance_of_alive_key(str(sample.key_expr))
        if instance is None:
            return
        with self._changed:
            if sample.kind == zenoh.SampleKind.PUT:
                # A token declared anew (a restart) wipes the suspicion.
                self._suspect.pop(instance, None)
                self._live.add(instance)
            else:
                self._live.discard(instance)
                self._suspect.pop(instance, None)
            self._events += 1
            self._changed.notify_all()

    def live(self):
        """The live instances, by name."""
        with self._lock:
            return sorted(self._live)

    def suspect(self, instance):
        """`instance` left a request unanswered: try it last for `suspect_for_s`."""
        with self._lock:
            self._suspect[instance] = time.monotonic() + self.suspect_for_s

    def order(self, vehicle_id):
        """The live instances in the order `vehicle_id` tries them now: rendezvous order,
        suspected ones moved to the end (in their rendezvous order)."""
        now = time.monotonic()
        with self._lock:
            self._suspect = {i: until for i, until in self._suspect.items() if until > now}
            order = rendezvous_order(vehicle_id, self._live)
            return sorted(order, key=lambda i: i in self._suspect)
