#!/usr/bin/env python3
"""Example client of the HMDP planner service over Zenoh, in Python.

Sends a perception snapshot (a JSON ``PlanRequest``, see docs/protocol.md) to a running
``planner serve`` and prints the decision it gets back as one JSON object per line::

    python3 hmdp_client.py --connect tcp/127.0.0.1:7447                 # built-in snapshot
    python3 hmdp_client.py --connect tcp/127.0.0.1:7447 --request snapshot.json
    python3 hmdp_client.py --connect tcp/127.0.0.1:7447 --steps 5 --stats
    python3 hmdp_client.py --connect tcp/127.0.0.1:7447 --planner-key planner.key.pub

The planner keeps no state per vehicle: its hysteresis memory travels with the messages.
``--steps N`` shows how a vehicle carries it: it sends N consecutive snapshots and feeds the
``memory`` of each decision into the next request. Between two snapshots the scene is moved
on by one planner period with a deliberately trivial model (the SVs keep their speed, the ego
follows the first step of its plan); a real vehicle sends what it perceives.

Output (stdout, one JSON object per line):

* a decision: ``{"step", "vehicle_id", "sequence", "layer", "action", "next_maneuver",
  "setpoint", "plan", "memory", "solve_us", "queue_us"}``;
* a rejection: ``{"step", "vehicle_id", "sequence", "rejected": {"reason", "field"}}``;
* with ``--stats``, last: ``{"stats": {...}}``, the planner's statistics document.

With ``--planner-key`` (the ``.pub`` file of ``planner keygen``) an answer that does not
verify (forged, unsigned) is refused, counted on stderr, and the real one awaited until the
timeout. Without a key every answer is taken (docs/protocol.md, "Authentication"): so the
client refuses an endpoint beyond this host, where anyone could answer, unless told
``--insecure`` (then said on stderr, in capitals). Loopback demos need no key. A request above
the planner's message limit (64 KiB with Zenoh's headers) is refused before it is sent: Zenoh
would drop it on the way, unanswered.

Every request carries its send time (``sent_at_ns``, Unix time in ns): a planner that gets
it older than its deadline answers ``stale_fallback`` at once.

Several planner instances (``planner serve --instance-id``, docs/deploy.md, "Scaling out"):
the client follows their liveliness tokens (``hmdp/planner/alive/<id>``), sends a vehicle's
requests to its instance, ``hmdp/planner/plan/<id>``, chosen by rendezvous hashing of the
vehicle id (the Rust channel's hash, so both pick the same instance for a vehicle), and when
no valid answer came within ``--retry-after`` (0.15 s) asks the next instance once and tries
the silent one last for ``--suspect-for`` (2 s). Each decision line then names the
``instance`` that answered. Without any token in sight, or with ``--no-failover``, requests
go to ``hmdp/planner/plan`` as before.

Exit code: 0 every request was decided, 2 a request was rejected (reason and field are also
printed on stderr; no later snapshot is sent), 1 no decision otherwise (no planner, timeout,
an answer this client cannot read or verify, a bad command line or request file).

Dependencies: eclipse-zenoh; cryptography for --planner-key (see requirements.txt).
"""

import argparse
import copy
import json
import queue
import sys
import threading
import time

import zenoh

import hmdp_signing
from hmdp_instances import (  # noqa: F401  (part of this client's API)
    ALIVE_KEYS,
    RETRY_AFTER_S,
    SUSPECT_FOR_S,
    Instances,
    instance_of_alive_key,
    rendezvous_order,
    rendezvous_score,
)

PLAN_KEY = "hmdp/planner/plan"  # queryable of `planner serve` (protocol::names)
STATS_KEY = "hmdp/planner/stats"  # statistics, published every second
PROTOCOL_VERSION = 3  # also in the iceoryx2 type names: hmdp::PlanRequest/v3
# The JSON form is chosen by the query's encoding; anything else is read as bincode.
JSON_ENCODING = "application/json"
# Every Zenoh session of the project drops a message above 64 KiB while reassembling it,
# unanswered (transport/link/rx/max_message_size); the key expression and Zenoh's headers
# travel with the payload (transport::zenoh::check_request_size, the same bound).
MAX_REQUEST_BYTES = 64 * 1024 - 1024

# Planner period (deploy/planner.toml, timing.step_s): one snapshot per period in --steps.
STEP_S = 0.4
# A lane change takes about 3 s: the lateral speed of the trivial ego model in --steps.
LANE_CHANGE_S = 3.0

# A 3-lane road, the ego cruising at 25 m/s in lane 2 (wanting 28 m/s) and a slower SV 110 m
# ahead in the same lane. The first decisions speed the ego up; a few periods later (with
# --steps) the gap has shrunk below the trigger distance: the SV enters corrective mode and
# its frozen thresholds appear in the memory, which carries them from then on.
EXAMPLE_REQUEST = {
    "version": PROTOCOL_VERSION,
    "vehicle_id": 7,
    "sequence": 1,
    "timestamp_ns": 1_000_000_000,
    "road": {"lanes": 3, "lane_width_m": 3.5, "speed_limit_mps": 30.0},
    "ego": {
        "x_m": 0.0,
        "y_m": 3.5,
        "v_mps": 25.0,
        "desired_speed_mps": 28.0,
        "maneuver": {"lane": 2, "beta": 0},
    },
    # Positions are vehicle centres; vy_mps is the lateral speed (positive to the left);
    # length_m / width_m 0 mean unknown (the planner assumes its default size).
    "svs": [
        {
            "id": 1,
            "x_m": 110.0,
            "y_m": 3.5,
            "v_mps": 22.0,
            "a_mps2": 0.0,
            "vy_mps": 0.0,
            "length_m": 4.5,
            "width_m": 1.8,
        }
    ],
    # First request: an empty memory (it may also be left out).
    "memory": {"corrective": [], "previous_plan": []},
}


class NoAnswer(Exception):
    """No usable answer from the planner (exit code 1)."""


class BadInput(Exception):
    """The request to send cannot be read or sent (exit code 1; the planner was not asked)."""


class RequestTooLarge(BadInput):
    """A request no planner could receive: Zenoh drops it on the way, unanswered."""


class Insecure(BadInput):
    """A planner beyond this host without its public key, and no --insecure."""


def check_security(endpoint, verifier, insecure):
    """Refuses (Insecure) a planner beyond this host whose answers cannot be verified
    (hmdp_signing.check_endpoint); with `insecure` it warns on stderr instead."""
    try:
        warning = hmdp_signing.check_endpoint(endpoint, verifier is not None, insecure)
    except hmdp_signing.UnverifiedPlanner as e:
        raise Insecure(str(e)) from e
    if warning:
        print(warning, file=sys.stderr)


class ArgumentParser(argparse.ArgumentParser):
    """Exits 1 on a bad command line (argparse's 2 is this client's "rejected")."""

    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(1, f"{self.prog}: error: {message}\n")


def open_session(endpoint):
    """A Zenoh client session that reaches the planner only through `endpoint`.

    Multicast scouting is off, as on the planner: nothing is discovered, the endpoint is all.
    """
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps("client"))
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    try:
        return zenoh.open(config)
    except zenoh.ZError as e:  # nothing listening there: a client session fails to open
        raise NoAnswer(f"cannot connect to {endpoint}: {e}") from e


def _response_of(reply):
    """The JSON response of a reply; NoAnswer if it cannot be read or is of another version."""
    try:
        response = json.loads(reply.ok.payload.to_bytes())
    except ValueError as e:  # not UTF-8 or not JSON: not the JSON form asked for
        raise NoAnswer(f"unreadable answer: {e}") from e
    # Another protocol version may be laid out differently: check it before anything else.
    if not isinstance(response, dict) or response.get("version") != PROTOCOL_VERSION:
        version = response.get("version") if isinstance(response, dict) else None
        raise NoAnswer(f"response of protocol version {version}, expected {PROTOCOL_VERSION}")
    return response


def _refusal(response, verifier, refused):
    """The signature error that refuses `response` (also appended to `refused`), or None."""
    if verifier is None:
        return None
    try:
        verifier.verify(response)
    except hmdp_signing.SignatureError as e:
        if refused is not None:
            refused.append(e)
        return e
    return None


def _ask_instances(session, request, payload, order, timeout_s, verifier, refused, instances):
    """One request to its vehicle's instance, `order[0]`, and once more to `order[1]` when no
    valid answer came within `instances.retry_after_s` (or that query ended without one).
    The first valid answer for this request (its vehicle id and sequence) wins."""
    start = time.monotonic()
    deadline = start + timeout_s
    retry_at = start + instances.retry_after_s
    expected = (request.get("vehicle_id"), request.get("sequence"))
    events = queue.Queue()

    def send(attempt, instance, wait_s):
        def on_reply(reply):
            events.put(("reply", attempt, reply))

        def on_end():  # Zenoh drops the callback when the query is over
            events.put(("end", attempt, None))

        try:
            # Target ALL: a forged queryable on the instance's key does not take the query
            # away from the instance (with --planner-key its answers are refused).
            session.get(
                f"{PLAN_KEY}/{instance}",
                zenoh.handlers.Callback(on_reply, on_end),
                target=zenoh.QueryTarget.ALL,
                consolidation=zenoh.ConsolidationMode.NONE,
                timeout=max(wait_s, 0.001),
                payload=payload,
                encoding=zenoh.Encoding(JSON_ENCODING),
            )
        except zenoh.ZError as e:
            print(f"query to planner instance {instance} not sent: {e}", file=sys.stderr)
            events.put(("end", attempt, None))

    send(0, order[0], timeout_s)
    sent, ended, why = 1, set(), None
    while True:
        may_retry = sent < min(len(order), 2)
        wake = min(retry_at, deadline) if may_retry else deadline
        try:
            kind, attempt, reply = events.get(timeout=max(wake - time.monotonic(), 0.0))
        except queue.Empty:
            kind = attempt = reply = None
        retry_now = False
        if kind == "reply":
            if reply.ok is not None:  # error replies (a query's "Timeout") carry no answer
                response = _response_of(reply)
                # A decision for another request is never taken (a rejection of an unreadable
                # request may echo 0 for both).
                mismatched = (response.get("vehicle_id"), response.get("sequence")) != expected
                if mismatched and "decided" in response.get("outcome", {}):
                    print(f"an answer for another request ignored: {response.get('vehicle_id')}/"
                          f"{response.get('sequence')}", file=sys.stderr)
                    continue
                error = _refusal(response, verifier, refused)
                if error is not None:
                    why = error
                    continue
                instances.last_instance = order[attempt]
                instances.last_retries = sent - 1
                return response
        elif kind == "end":
            ended.add(attempt)
            if len(ended) == sent and not may_retry:
                break
            # The instance's query ended without a valid answer (it went away, or only
            # refused answers came): no reason to wait for the retry time, if time is left.
            retry_now = may_retry and len(ended) == sent and time.monotonic() < deadline
        elif time.monotonic() >= deadline:
            break
        else:
            retry_now = may_retry
        if retry_now:
            silent, following = order[0], order[1]
            elapsed_ms = (time.monotonic() - start) * 1e3
            print(f"planner instance {silent} gave no answer in {elapsed_ms:.0f} ms: asking {following}",
                  file=sys.stderr)
            instances.suspect(silent)
            send(1, following, deadline - time.monotonic())
            sent += 1
    instances.last_instance, instances.last_retries = None, sent - 1
    if why is not None:
        raise NoAnswer(f"no verified answer within {timeout_s} s (refused: {why})")
    raise NoAnswer(f"no answer within {timeout_s} s from planner instances {order[:sent]}")


def ask(session, request, timeout_s, verifier=None, refused=None, instances=None):
    """Sends one PlanRequest (a dict) as JSON, stamped with its send time; returns the
    PlanResponse as a dict.

    With `verifier` (a hmdp_signing.Verifier) an answer that does not verify is refused (its
    SignatureError is appended to `refused`, a list, when given) and the next one is awaited.

    With `instances` (an `Instances` of this session) and planner instances in sight, the
    request goes to its vehicle's instance, with one retry on the next (`_ask_instances`);
    without, to the plain key `PLAN_KEY`.
    """
    request["sent_at_ns"] = time.time_ns()
    payload = json.dumps(request).encode()
    if len(payload) > MAX_REQUEST_BYTES:
        # Zenoh would drop it on the way and the planner never see it: no answer could come.
        raise RequestTooLarge(
            f"a request of {len(payload)} bytes: the planner receives at most {MAX_REQUEST_BYTES} "
            "(Zenoh drops larger messages unanswered)"
        )
    vehicle_id = request.get("vehicle_id")
    order = []
    # A vehicle id the planner will reject anyway (not a u64) goes to the plain key.
    if instances is not None and type(vehicle_id) is int and 0 <= vehicle_id < 1 << 64:
        order = instances.order(vehicle_id)
    if order:
        return _ask_instances(session, request, payload, order, timeout_s, verifier, refused, instances)
    if instances is not None:
        instances.last_instance, instances.last_retries = None, 0
    replies = session.get(
        PLAN_KEY,
        payload=payload,
        encoding=zenoh.Encoding(JSON_ENCODING),
        timeout=timeout_s,
        # Every reply as it comes: with consolidation a forged reply could hide the planner's.
        consolidation=zenoh.ConsolidationMode.NONE,
    )
    why = None
    # The planner sends exactly one reply; the loop ends at the first one taken, when every
    # queryable has replied, or at the timeout.
    for reply in replies:
        if reply.ok is None:
            # Zenoh itself answers "Timeout" when the query's timeout runs out.
            error = reply.err.payload.to_string()
            if error == "Timeout":
                break
            raise NoAnswer(f"error reply: {error}")
        response = _response_of(reply)
        error = _refusal(response, verifier, refused)
        if error is not None:
            why = error
            continue
        return response
    if why is not None:
        raise NoAnswer(f"no verified answer within {timeout_s} s (refused: {why})")
    raise NoAnswer(f"no answer within {timeout_s} s")


def summary(step, response):
    """The line printed for one response: the decision, or the rejection."""
    head = {"step": step, "vehicle_id": response["vehicle_id"], "sequence": response["sequence"]}
    outcome = response["outcome"]
    if "rejected" in outcome:
        return {**head, "rejected": outcome["rejected"]}
    decided = outcome["decided"]
    return {
        **head,
        # nominal, global_relaxation, fallback, watchdog_fallback or stale_fallback
        "layer": decided["layer"],
        "action": decided["action"],  # first action of the plan
        "next_maneuver": decided["next_maneuver"],  # the maneuver to command now
        "setpoint": decided["setpoint"],  # accel_mps2 to command now, target_speed_mps at the step's end
        "plan": decided["plan"],
        "memory": decided["memory"],  # to send back, unchanged, with the next request
        "solve_us": response["solve_us"],
        "queue_us": response["queue_us"],
    }


def lane_centre(road, lane):
    """Lateral position of a lane centre; lane 1 is the leftmost (docs/protocol.md)."""
    return (road["lanes"] - lane) * road["lane_width_m"]


def next_request(request, decided):
    """The snapshot one period later, carrying the memory `decided` returned.

    Trivial scene model, enough for a plausible sequence: the SVs keep their speed; the ego
    reaches the position and speed of the plan's first step and moves sideways towards the
    centre of the lane it now heads for.
    """
    nxt = copy.deepcopy(request)
    nxt["sequence"] += 1
    nxt["timestamp_ns"] += int(STEP_S * 1e9)
    ego = nxt["ego"]
    # The ego does what the planner predicted for its first step (the planner's own model).
    ego["x_m"] = decided["plan"][0]["x_m"]
    ego["v_mps"] = decided["plan"][0]["v_mps"]
    ego["maneuver"] = decided["next_maneuver"]
    target_y = lane_centre(nxt["road"], ego["maneuver"]["lane"])
    max_dy = nxt["road"]["lane_width_m"] * STEP_S / LANE_CHANGE_S
    ego["y_m"] += max(-max_dy, min(max_dy, target_y - ego["y_m"]))
    for sv in nxt["svs"]:
        sv["x_m"] += sv["v_mps"] * STEP_S
    # The hysteresis state: without it the planner would trigger and release corrective mode
    # afresh every period.
    nxt["memory"] = decided["memory"]
    return nxt


class StatsListener:
    """Keeps the latest statistics document the planner published."""

    def __init__(self, session):
        self.latest = None
        self.received = threading.Event()
        self.subscriber = session.declare_subscriber(STATS_KEY, self._on_sample)

    def _on_sample(self, sample):
        self.latest = json.loads(sample.payload.to_bytes())
        self.received.set()

    def wait(self, timeout_s):
        """The latest document; waits up to `timeout_s` for a first one."""
        self.received.wait(timeout_s)
        return self.latest


def load_request(path):
    if path is None:
        return copy.deepcopy(EXAMPLE_REQUEST)
    try:
        with open(path, encoding="utf-8") as f:
            request = json.load(f)
    except (OSError, ValueError) as e:
        raise BadInput(f"cannot read {path}: {e}") from e
    if not isinstance(request, dict):
        raise BadInput(f"{path}: a PlanRequest is a JSON object")
    # Both may be omitted in the JSON form; --steps needs the memory field to carry it.
    request.setdefault("memory", {"corrective": [], "previous_plan": []})
    return request


def run(args):
    request = load_request(args.request)
    try:
        verifier = hmdp_signing.Verifier.from_file(args.planner_key) if args.planner_key else None
    except (OSError, ValueError, ImportError) as e:
        raise BadInput(f"planner key {args.planner_key}: {e}") from e
    check_security(args.connect, verifier, args.insecure)
    refused = []
    session = open_session(args.connect)
    try:
        stats = StatsListener(session) if args.stats else None
        instances = None if args.no_failover else Instances(session, args.retry_after, args.suspect_for)
        code = 0
        for step in range(1, args.steps + 1):
            response = ask(session, request, args.timeout, verifier, refused, instances)
            line = summary(step, response)
            if instances is not None:
                # Who answered (None: the plain key, no instance in sight), after how many resends.
                line["instance"] = instances.last_instance
                line["retries"] = instances.last_retries
            print(json.dumps(line, indent=2 if args.pretty else None), flush=True)
            if "rejected" in line:
                r = line["rejected"]
                print(f"rejected: {r['reason']} (field: {r['field'] or '-'})", file=sys.stderr)
                code = 2
                break
            if step < args.steps:
                request = next_request(request, response["outcome"]["decided"])
        if stats is not None:
            # Published every second: at most a little over a second to wait.
            document = stats.wait(2.0)
            if document is None:
                print("no statistics received", file=sys.stderr)
            else:
                print(json.dumps({"stats": document}, indent=2 if args.pretty else None), flush=True)
        return code
    finally:
        if refused:
            print(f"refused {len(refused)} answers that did not verify: {refused[-1]}", file=sys.stderr)
        session.close()


def main(argv=None):
    parser = ArgumentParser(description="Ask the HMDP planner for a decision over Zenoh (JSON).")
    parser.add_argument("--connect", default="tcp/127.0.0.1:7447", help="planner endpoint (tcp/HOST:PORT)")
    parser.add_argument("--request", metavar="FILE.json", help="PlanRequest to send (default: built-in example)")
    parser.add_argument("--timeout", type=float, default=1.0, help="seconds to wait for each answer")
    parser.add_argument("--steps", type=int, default=1, help="consecutive snapshots, carrying the memory")
    parser.add_argument("--stats", action="store_true", help="also print the planner's statistics")
    parser.add_argument("--pretty", action="store_true", help="indent the JSON output")
    parser.add_argument(
        "--planner-key", metavar="FILE.pub", help="the planner's public key: refuse answers that do not verify"
    )
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="without --planner-key, ask a planner beyond this host anyway (its answers are not verified)",
    )
    parser.add_argument(
        "--retry-after",
        type=float,
        default=RETRY_AFTER_S,
        metavar="S",
        help="several planner instances: without a valid answer this long, ask the next instance once",
    )
    parser.add_argument(
        "--suspect-for",
        type=float,
        default=SUSPECT_FOR_S,
        metavar="S",
        help="how long an instance that left a request unanswered is tried last",
    )
    parser.add_argument(
        "--no-failover",
        action="store_true",
        help="ignore the planner instances: every request to hmdp/planner/plan",
    )
    parser.add_argument(
        "--print-example", action="store_true", help="print the built-in snapshot (a template for --request) and exit"
    )
    args = parser.parse_args(argv)
    if args.print_example:
        print(json.dumps(EXAMPLE_REQUEST, indent=2))
        return 0
    if args.steps < 1:
        parser.error("--steps must be at least 1")
    try:
        return run(args)
    except (NoAnswer, BadInput) as e:
        print(f"no decision: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
