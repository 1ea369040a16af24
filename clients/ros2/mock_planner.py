#!/usr/bin/env python3
"""A stand-in for the planner's ROS 2 node, to test hmdp_ros2_client.py without it.

Serves ``/hmdp/plan`` (``hmdp_msgs/srv/Plan``) and answers every request with a canned
decision made from the request (keep lane, hold speed, three steps), or with a typed
rejection for the few invalid inputs the client's ``reject`` sends (beta outside -1..=1, a
non-finite ego speed, lane 0 or beyond the road, two SVs with one id). Every answer is
published on ``/hmdp/decisions``; a decision's plan also as a ``MarkerArray`` on
``/hmdp/plan_markers`` (namespaces ``ego``, ``plan``, ``svs``). QoS reliable, keep-last 10.

    VENV/bin/python mock_planner.py [--max-seconds S]

Stops on SIGINT/SIGTERM, or after ``--max-seconds`` (default 300) so that it never lingers.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from typing import Any

import rclpy
from geometry_msgs.msg import Point
from hmdp_msgs.msg import (
    Action,
    Decided,
    Maneuver,
    PlannerMemory,
    PlanRequest,
    PlanResponse,
    PlanStep,
    Rejected,
    SetPoint,
)
from hmdp_msgs.srv import Plan
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from visualization_msgs.msg import Marker, MarkerArray

from hmdp_ros2_client import DECISIONS_TOPIC, MARKERS_TOPIC, PLAN_SERVICE, QOS

STEP_S = 0.4  # the planner's decision period
HORIZON = 3


def check(request: PlanRequest) -> tuple[int, str] | None:
    """The rejection (reason code, field) of an invalid request, None for a valid one."""
    if request.version != 3:
        return Rejected.REASON_UNSUPPORTED_VERSION, "version"
    if not math.isfinite(request.ego.v_mps):
        return Rejected.REASON_NON_FINITE, "ego.v_mps"
    if not 1 <= request.ego.maneuver.lane <= request.road.lanes:
        return Rejected.REASON_LANE_OUT_OF_RANGE, "ego.maneuver.lane"
    if not -1 <= request.ego.maneuver.beta <= 1:
        return Rejected.REASON_BETA_OUT_OF_RANGE, "ego.maneuver.beta"
    ids = [sv.id for sv in request.svs]
    if len(set(ids)) != len(ids):
        return Rejected.REASON_DUPLICATE_SV_ID, "sv.id"
    return None


def canned_answer(request: PlanRequest) -> PlanResponse:
    """The mock's answer: deterministic, a function of the request only."""
    response = PlanResponse(
        version=3,
        vehicle_id=request.vehicle_id,
        sequence=request.sequence,
        solve_us=100,
        queue_us=1,
    )
    rejection = check(request)
    if rejection is not None:
        response.outcome = PlanResponse.OUTCOME_REJECTED
        response.solve_us = 0
        response.rejected = Rejected(reason=rejection[0], field=rejection[1])
        return response
    ego = request.ego
    keep = Maneuver(lane=ego.maneuver.lane, beta=ego.maneuver.beta)
    plan = [
        PlanStep(
            action=Action(lateral=0, longitudinal=0),
            maneuver=Maneuver(lane=keep.lane, beta=keep.beta),
            x_m=ego.x_m + ego.v_mps * STEP_S * (k + 1),
            v_mps=ego.v_mps,
            occupied_lanes=1 << (keep.lane - 1),
        )
        for k in range(HORIZON)
    ]
    response.outcome = PlanResponse.OUTCOME_DECIDED
    response.decided = Decided(
        action=Action(lateral=0, longitudinal=0),
        next_maneuver=keep,
        setpoint=SetPoint(accel_mps2=0.0, target_speed_mps=ego.v_mps),
        plan=plan,
        layer=Decided.LAYER_NOMINAL,
        memory=PlannerMemory(corrective=[], previous_plan=[Action() for _ in range(HORIZON)]),
    )
    return response


def lane_y(request: PlanRequest, lane: int) -> float:
    return (request.road.lanes - lane) * request.road.lane_width_m


def markers_of(request: PlanRequest, response: PlanResponse) -> MarkerArray:
    """The plan as markers: the ego (a cube), the plan (a line strip), the SVs (cubes)."""
    frame = "road"
    ego = Marker(ns="ego", id=0, type=Marker.CUBE, action=Marker.ADD)
    ego.header.frame_id = frame
    ego.pose.position.x, ego.pose.position.y = request.ego.x_m, request.ego.y_m
    ego.scale.x, ego.scale.y, ego.scale.z = 4.5, 1.8, 1.5
    ego.color.b, ego.color.a = 1.0, 1.0
    plan = Marker(ns="plan", id=0, type=Marker.LINE_STRIP, action=Marker.ADD)
    plan.header.frame_id = frame
    plan.scale.x = 0.3
    plan.color.g, plan.color.a = 1.0, 1.0
    plan.points = [Point(x=request.ego.x_m, y=request.ego.y_m)] + [
        Point(x=step.x_m, y=lane_y(request, step.maneuver.lane)) for step in response.decided.plan
    ]
    svs = []
    for sv in request.svs:
        m = Marker(ns="svs", id=int(sv.id), type=Marker.CUBE, action=Marker.ADD)
        m.header.frame_id = frame
        m.pose.position.x, m.pose.position.y = sv.x_m, sv.y_m
        m.scale.x, m.scale.y, m.scale.z = sv.length_m or 4.5, sv.width_m or 1.8, 1.5
        m.color.r, m.color.a = 1.0, 1.0
        svs.append(m)
    return MarkerArray(markers=[ego, plan, *svs])


class MockPlanner(Node):
    """The node: the Plan service and the two publishers."""

    def __init__(self) -> None:
        super().__init__("hmdp_mock_planner")
        self.decisions = self.create_publisher(PlanResponse, DECISIONS_TOPIC, QOS)
        self.markers = self.create_publisher(MarkerArray, MARKERS_TOPIC, QOS)
        self.service = self.create_service(Plan, PLAN_SERVICE, self.on_plan, qos_profile=QOS)
        self.answered = 0

    def on_plan(self, call: Plan.Request, result: Plan.Response) -> Plan.Response:
        response = canned_answer(call.request)
        self.decisions.publish(response)
        if response.outcome == PlanResponse.OUTCOME_DECIDED:
            self.markers.publish(markers_of(call.request, response))
        self.answered += 1
        result.response = response
        return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-seconds", type=float, default=300.0)
    args = parser.parse_args(argv)
    rclpy.init()
    node = MockPlanner()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop: dict[str, Any] = {"now": False}

    def on_signal(_signum: int, _frame: Any) -> None:
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    print(f"mock planner: serving {PLAN_SERVICE}", file=sys.stderr, flush=True)
    deadline = time.monotonic() + args.max_seconds
    try:
        while not stop["now"] and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(f"mock planner: answered {node.answered}", file=sys.stderr, flush=True)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
