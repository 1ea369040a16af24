#!/usr/bin/env python3
"""The planner over ROS 2, from rclpy: a command-line tool and a library to copy.

The planner's ROS 2 node serves the service ``/hmdp/plan`` (``hmdp_msgs/srv/Plan``),
publishes every answer on ``/hmdp/decisions`` (``hmdp_msgs/msg/PlanResponse``) and the plan
as ``visualization_msgs/msg/MarkerArray`` on ``/hmdp/plan_markers``; QoS reliable,
keep-last 10, volatile, for all three. ``hmdp_msgs`` mirrors protocol version 3
(docs/protocol.md) field by field; ROS has no unions, so ``PlanResponse.outcome`` says which
of ``decided`` and ``rejected`` holds the answer.

Subcommands (each prints one JSON document on stdout, logs go to stderr, exit code 0 on
success, 1 on a failed check, 2 on an error such as no planner in sight):

    replay RECORDING.mcap [...] [--timeout S]   re-send a planner recording, compare answers
    reject [--timeout S]                        send invalid requests, print the rejections
    markers [--count N] [--timeout S]           count /hmdp/decisions and /hmdp/plan_markers
    cdr PlanRequest|PlanResponse < doc.json     the CDR bytes rclpy makes of a JSON document

Run it with the venv of scripts/ros2-env (``VENV/bin/python hmdp_ros2_client.py ...``). The
ROS environment is respected as it is: ``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``.

Library: the conversions between the protocol's JSON form and the hmdp_msgs messages, and
their CDR bytes, are in hmdp_ros2_convert.py; ``PlannerLink`` here is a node with the Plan
client and bounded, event-driven waits.
"""

from __future__ import annotations

import argparse
import copy
import json
import logging
import math
import struct
import sys
import time
from collections import Counter, defaultdict, deque
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import rclpy
from hmdp_msgs.msg import PlanRequest, PlanResponse
from hmdp_msgs.srv import Plan
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from visualization_msgs.msg import MarkerArray

from hmdp_ros2_convert import (
    ConversionError,
    LAYER_NAMES,
    REASON_NAMES,
    TIMING_LAYERS,
    WORKED_REQUEST,
    cdr_hex,
    json_safe,
    request_from_json,
    response_from_json,
    response_to_json,
)

LOG = logging.getLogger("hmdp_ros2_client")

PLAN_SERVICE = "/hmdp/plan"
DECISIONS_TOPIC = "/hmdp/decisions"
MARKERS_TOPIC = "/hmdp/plan_markers"

# Reliable, keep-last 10, volatile: the service and both topics.
QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


# ---------------------------------------------------------------------------------------------
# rclpy: the planner link
# ---------------------------------------------------------------------------------------------


class TopicCounter:
    """A subscription (reliable, keep-last 10) that counts messages and matched publishers."""

    def __init__(self, node: Node, msg_type: type, topic: str) -> None:
        self.topic = topic
        self.count = 0
        self.last: Any = None
        self.received: list[Any] = []
        self.matched = 0
        callbacks = SubscriptionEventCallbacks(matched=self._on_matched)
        self.subscription = node.create_subscription(
            msg_type, topic, self._on_message, QOS, event_callbacks=callbacks
        )

    def _on_message(self, msg: Any) -> None:
        self.count += 1
        self.last = msg
        self.received.append(msg)

    def _on_matched(self, info: Any) -> None:
        self.matched = int(info.current_count)

    def publishers(self) -> int:
        """Publishers matched with this subscription (the event's count, or the graph's)."""
        return max(self.matched, self.subscription.get_publisher_count())


class PlannerLink:
    """A node with the ``/hmdp/plan`` client, and optionally subscriptions to the planner's
    topics; every wait is bounded and driven by the executor's events."""

    def __init__(self, name: str = "hmdp_ros2_client", subscribe: bool = False) -> None:
        self.node = rclpy.create_node(name)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.client = self.node.create_client(Plan, PLAN_SERVICE, qos_profile=QOS)
        self.decisions: TopicCounter | None = None
        self.markers: TopicCounter | None = None
        if subscribe:
            self.decisions = TopicCounter(self.node, PlanResponse, DECISIONS_TOPIC)
            self.markers = TopicCounter(self.node, MarkerArray, MARKERS_TOPIC)

    def wait_for_service(self, timeout_s: float) -> bool:
        """Waits at most ``timeout_s`` for a ``/hmdp/plan`` server (rclpy's wait_for_service)."""
        start = time.monotonic()
        ok = self.client.wait_for_service(timeout_sec=timeout_s)
        LOG.info(
            "service %s %s after %.2f s",
            PLAN_SERVICE,
            "available" if ok else "NOT available",
            time.monotonic() - start,
        )
        return ok

    def spin_until(self, condition: Callable[[], bool], timeout_s: float) -> bool:
        """Runs callbacks until ``condition()`` holds or ``timeout_s`` has passed."""
        deadline = time.monotonic() + timeout_s
        while not condition():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self.executor.spin_once(timeout_sec=remaining)
        return True

    def wait_for_topics(self, timeout_s: float) -> bool:
        """Waits until both subscriptions have matched a publisher of the planner."""
        assert self.decisions is not None and self.markers is not None
        start = time.monotonic()
        ok = self.spin_until(
            lambda: self.decisions.publishers() > 0 and self.markers.publishers() > 0, timeout_s
        )
        LOG.info(
            "subscriptions matched: %s %d, %s %d after %.2f s",
            DECISIONS_TOPIC,
            self.decisions.publishers(),
            MARKERS_TOPIC,
            self.markers.publishers(),
            time.monotonic() - start,
        )
        return ok

    def plan(self, request: PlanRequest, timeout_s: float) -> PlanResponse | None:
        """Sends one request and waits at most ``timeout_s`` for its answer (None: none came)."""
        future = self.client.call_async(Plan.Request(request=request))
        self.executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        if not future.done():
            self.client.remove_pending_request(future)
            return None
        return future.result().response

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()


def stamped(request: dict[str, Any], sequence: int | None = None) -> dict[str, Any]:
    """A copy of a JSON request with ``sent_at_ns`` set to now (and another sequence)."""
    out = copy.deepcopy(request)
    out["sent_at_ns"] = time.time_ns()
    if sequence is not None:
        out["sequence"] = sequence
    return out


# ---------------------------------------------------------------------------------------------
# replay
# ---------------------------------------------------------------------------------------------


def read_recording(
    paths: Iterable[str],
) -> tuple[list[dict[str, Any]], dict[tuple[int, int], deque]]:
    """The requests (in log-time order) and the answers by (vehicle_id, sequence) of planner
    recordings (``/planner/request``, ``/planner/response``; docs/recording.md)."""
    from mcap.reader import make_reader  # only replay needs it

    requests: list[tuple[int, dict[str, Any]]] = []
    answers: dict[tuple[int, int], list[tuple[int, dict[str, Any]]]] = defaultdict(list)
    for path in paths:
        with open(path, "rb") as f:
            reader = make_reader(f)
            for _schema, channel, message in reader.iter_messages(
                topics=["/planner/request", "/planner/response"]
            ):
                doc = json.loads(message.data)
                if channel.topic == "/planner/request":
                    requests.append((message.log_time, doc))
                else:
                    key = (int(doc["vehicle_id"]), int(doc["sequence"]))
                    answers[key].append((message.log_time, doc))
    requests.sort(key=lambda item: item[0])
    by_key = {
        k: deque(doc for _t, doc in sorted(v, key=lambda item: item[0])) for k, v in answers.items()
    }
    return [doc for _t, doc in requests], by_key


def _same(a: Any, b: Any) -> bool:
    """Deep equality with floats compared bit for bit (NaN equals NaN, -0.0 differs from 0.0)."""
    if isinstance(a, float) or isinstance(b, float):
        if not (isinstance(a, float) and isinstance(b, float)):
            return False
        return struct.pack("<d", a) == struct.pack("<d", b)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


def differing_fields(recorded: dict[str, Any], replayed: dict[str, Any]) -> list[str]:
    """The fields in which two answers (JSON form, normalized) differ, ignoring ``solve_us``,
    ``queue_us`` and ``signature``."""
    fields = [k for k in ("version", "vehicle_id", "sequence") if recorded[k] != replayed[k]]
    ((kind_a, a),) = recorded["outcome"].items()
    ((kind_b, b),) = replayed["outcome"].items()
    if kind_a != kind_b:
        return fields + ["outcome"]
    keys = (
        ("action", "next_maneuver", "setpoint", "plan", "layer", "memory")
        if kind_a == "decided"
        else ("reason", "field")
    )
    return fields + [k for k in keys if not _same(a[k], b[k])]


def run_replay(args: argparse.Namespace) -> tuple[int, Any]:
    """Sends every recorded request and compares each answer with the recorded one."""
    try:
        requests, answers = read_recording(args.recording)
    except Exception as err:  # a missing, truncated or corrupt file
        return 2, {"error": f"cannot read {' '.join(args.recording)}: {err}"}
    if not requests:
        return 2, {"error": f"no /planner/request message in {' '.join(args.recording)}"}
    link = PlannerLink("hmdp_ros2_replay")
    try:
        if not link.wait_for_service(args.discovery_timeout):
            return 2, {
                "error": f"service {PLAN_SERVICE} not available after {args.discovery_timeout} s"
            }
        report: dict[str, Any] = {
            "sent": 0,
            "identical": 0,
            "different": 0,
            "differences": [],
            "unanswered": 0,
            "timing_fallbacks_not_compared": 0,
            "without_recorded_answer": 0,
        }
        for i, doc in enumerate(requests):
            try:
                msg = request_from_json(stamped(doc))
            except ConversionError as err:
                return 2, {"error": f"recorded request #{i + 1}: {err}"}
            key = (int(msg.vehicle_id), int(msg.sequence))
            queue = answers.get(key)
            recorded = queue.popleft() if queue else None
            answer = link.plan(msg, args.timeout)
            report["sent"] += 1
            if answer is None:
                report["unanswered"] += 1
                LOG.warning("vehicle %d sequence %d: no answer within %.1f s", *key, args.timeout)
                continue
            if recorded is None:
                report["without_recorded_answer"] += 1
                continue
            try:
                expected = response_to_json(response_from_json(recorded))
            except ConversionError as err:
                return 2, {"error": f"recorded answer of vehicle {key[0]} sequence {key[1]}: {err}"}
            if (
                "decided" in expected["outcome"]
                and expected["outcome"]["decided"]["layer"] in TIMING_LAYERS
            ):
                report["timing_fallbacks_not_compared"] += 1
                continue
            got = response_to_json(answer)
            fields = differing_fields(expected, got)
            if not fields:
                report["identical"] += 1
                continue
            report["different"] += 1
            if len(report["differences"]) < 10:
                report["differences"].append(
                    {
                        "vehicle_id": key[0],
                        "sequence": key[1],
                        "fields": fields,
                        "recorded": json_safe(expected["outcome"]),
                        "replayed": json_safe(got["outcome"]),
                    }
                )
        failed = report["different"] > 0 or report["unanswered"] > 0
        return (1 if failed else 0), report
    finally:
        link.close()


# ---------------------------------------------------------------------------------------------
# reject, markers
# ---------------------------------------------------------------------------------------------


def rejection_cases() -> list[tuple[str, str, dict[str, Any]]]:
    """Invalid requests made from the worked example: (case, expected reason, request)."""
    cases = []
    beta = copy.deepcopy(WORKED_REQUEST)
    beta["ego"]["maneuver"]["beta"] = 5
    cases.append(("beta_5", "beta_out_of_range", beta))
    nan = copy.deepcopy(WORKED_REQUEST)
    nan["ego"]["v_mps"] = math.nan
    cases.append(("nan_ego_speed", "non_finite", nan))
    lane = copy.deepcopy(WORKED_REQUEST)
    lane["ego"]["maneuver"]["lane"] = 0
    cases.append(("lane_0", "lane_out_of_range", lane))
    dup = copy.deepcopy(WORKED_REQUEST)
    dup["svs"].append(dict(dup["svs"][0], x_m=60.0))
    cases.append(("duplicate_sv_id", "duplicate_sv_id", dup))
    return cases


def run_reject(args: argparse.Namespace) -> tuple[int, Any]:
    """Sends each invalid request and lists the answers; fails unless each is the expected
    typed rejection."""
    link = PlannerLink("hmdp_ros2_reject")
    try:
        if not link.wait_for_service(args.discovery_timeout):
            return 2, {
                "error": f"service {PLAN_SERVICE} not available after {args.discovery_timeout} s"
            }
        results = []
        ok = True
        for i, (case, expected, doc) in enumerate(rejection_cases()):
            answer = link.plan(request_from_json(stamped(doc, sequence=1000 + i)), args.timeout)
            entry: dict[str, Any] = {"case": case, "expected_reason": expected}
            if answer is None:
                entry.update(outcome="unanswered", reason=None, reason_name=None, field=None)
            elif answer.outcome == PlanResponse.OUTCOME_REJECTED:
                code = int(answer.rejected.reason)
                entry.update(
                    outcome="rejected",
                    reason=code,
                    reason_name=REASON_NAMES.get(code),
                    field=str(answer.rejected.field),
                )
            else:
                entry.update(
                    outcome="decided",
                    reason=None,
                    reason_name=None,
                    field=None,
                    layer=LAYER_NAMES.get(int(answer.decided.layer)),
                )
            ok = ok and entry["reason_name"] == expected
            results.append(entry)
        return (0 if ok else 1), results
    finally:
        link.close()


def run_markers(args: argparse.Namespace) -> tuple[int, Any]:
    """Sends the worked request ``--count`` times and counts what the planner published."""
    link = PlannerLink("hmdp_ros2_markers", subscribe=True)
    assert link.decisions is not None and link.markers is not None
    try:
        if not link.wait_for_service(args.discovery_timeout):
            return 2, {
                "error": f"service {PLAN_SERVICE} not available after {args.discovery_timeout} s"
            }
        if not link.wait_for_topics(args.discovery_timeout):
            return 2, {
                "error": f"no publisher matched on {DECISIONS_TOPIC} and {MARKERS_TOPIC} "
                f"after {args.discovery_timeout} s",
                "matched": {
                    "decisions": link.decisions.publishers(),
                    "plan_markers": link.markers.publishers(),
                },
            }
        sent = answered = 0
        sequences = set()
        for i in range(args.count):
            sequence = int(WORKED_REQUEST["sequence"]) + i
            answer = link.plan(request_from_json(stamped(WORKED_REQUEST, sequence)), args.timeout)
            sent += 1
            if answer is not None:
                answered += 1
                sequences.add(sequence)
        decisions, markers = link.decisions, link.markers

        def ours() -> int:
            """Decisions published for the requests answered here."""
            vehicle = WORKED_REQUEST["vehicle_id"]
            return sum(
                1
                for d in decisions.received
                if int(d.vehicle_id) == vehicle and int(d.sequence) in sequences
            )

        # What was published before the last answer arrived has been taken already; wait
        # (bounded) for the rest.
        link.spin_until(lambda: ours() >= answered and markers.count >= answered, args.timeout)
        last: dict[str, Any] | None = None
        if markers.last is not None:
            namespaces = Counter(m.ns for m in markers.last.markers)
            last = {
                "markers": len(markers.last.markers),
                "namespaces": dict(sorted(namespaces.items())),
            }
        report = {
            "sent": sent,
            "answered": answered,
            "decisions": decisions.count,
            "decisions_of_these_requests": ours(),
            "marker_arrays": markers.count,
            "last_marker_array": last,
            "matched": {"decisions": decisions.publishers(), "plan_markers": markers.publishers()},
        }
        ok = answered == sent and ours() == sent and markers.count >= sent
        return (0 if ok else 1), report
    finally:
        link.close()


# ---------------------------------------------------------------------------------------------
# cdr
# ---------------------------------------------------------------------------------------------


def run_cdr(args: argparse.Namespace) -> tuple[int, Any]:
    """Reads a JSON document on stdin and returns rclpy's CDR bytes of it as hex."""
    try:
        doc = json.load(sys.stdin)
        msg = request_from_json(doc) if args.type == "PlanRequest" else response_from_json(doc)
    except (ValueError, ConversionError) as err:
        return 2, {"error": f"{args.type}: {err}"}
    return 0, cdr_hex(msg, raw=args.raw)


# ---------------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------------


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="hmdp_ros2_client.py",
        description="Talk to the HMDP planner's ROS 2 node from rclpy.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    def waits(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--timeout", type=float, default=2.0, help="seconds to wait for each answer (default 2)"
        )
        p.add_argument(
            "--discovery-timeout",
            type=float,
            default=20.0,
            help="seconds to wait for the service and the topics to match (default 20)",
        )

    p = sub.add_parser("replay", help="re-send a planner recording's requests, compare the answers")
    p.add_argument("recording", nargs="+", help="MCAP files (/planner/request, /planner/response)")
    waits(p)
    p = sub.add_parser("reject", help="send invalid requests, print the typed rejections")
    waits(p)
    p = sub.add_parser(
        "markers", help="send the worked request N times, count the published topics"
    )
    p.add_argument("--count", type=int, default=5, help="requests to send (default 5)")
    waits(p)
    p = sub.add_parser("cdr", help="rclpy's CDR bytes (hex) of a JSON document read on stdin")
    p.add_argument("type", choices=("PlanRequest", "PlanResponse"))
    p.add_argument(
        "--raw",
        action="store_true",
        help="rclpy's bytes as they are (padding bytes are then whatever its buffer held)",
    )
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Runs one subcommand and prints its JSON document; returns the exit code."""
    logging.basicConfig(
        stream=sys.stderr, level=logging.INFO, format="hmdp_ros2_client: %(message)s"
    )
    args = parse_args(argv)
    runners = {"replay": run_replay, "reject": run_reject, "markers": run_markers, "cdr": run_cdr}
    if args.command == "cdr":
        code, doc = run_cdr(args)
    else:
        rclpy.init()
        try:
            code, doc = runners[args.command](args)
        finally:
            rclpy.try_shutdown()
    if args.command == "cdr" and code == 0:
        print(doc, flush=True)  # the bare hex string: easy to compare from any language
    else:
        print(json.dumps(json_safe(doc)), flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
