"""SUMO's view of the road and the protocol's (docs/protocol.md), and the mapping between them.

SUMO: lane index 0 is the RIGHTMOST lane; a vehicle's lane position is the position of its
FRONT along the lane; its lateral lane position is the offset of its centre from the centre of
its current lane, positive to the left; lateral speed positive to the left.

Protocol: lane 1 is the LEFTMOST lane and lane i has its centre at y = (lanes - i) * width;
x and y are the vehicle's CENTRE; lateral speed positive to the left.

So SUMO lane k is protocol lane lanes - k, whose centre is at y = k * width: y is the SUMO
lane index times the width plus the lateral offset (a vehicle half way through a lane
change reads lane k with an offset up to half a lane, which puts it on the lane boundary).
"""

import traci.constants as tc

# The context subscription's variables, per vehicle, and the ego's own.
VEHICLE_VARIABLES = (
    tc.VAR_LANEPOSITION,
    tc.VAR_LANE_INDEX,
    tc.VAR_LANEPOSITION_LAT,
    tc.VAR_SPEED,
    tc.VAR_ACCELERATION,
    tc.VAR_SPEED_LAT,
    tc.VAR_LENGTH,
    tc.VAR_WIDTH,
)

PROTOCOL_VERSION = 3
MAX_SVS = 64  # protocol::MAX_SVS: the nearest this many go into a request


def protocol_lane(sumo_index, lanes):
    """SUMO lane index (0 = rightmost) to protocol lane (1 = leftmost)."""
    if not 0 <= sumo_index < lanes:
        raise ValueError(f"SUMO lane index {sumo_index} not on a {lanes}-lane road")
    return lanes - sumo_index


def sumo_lane_index(lane, lanes):
    """Protocol lane (1 = leftmost) to SUMO lane index (0 = rightmost)."""
    if not 1 <= lane <= lanes:
        raise ValueError(f"protocol lane {lane} not on a {lanes}-lane road")
    return lanes - lane


def centre_x(front_position_m, length_m):
    """A vehicle's centre from SUMO's front position (straight road along its lanes)."""
    return front_position_m - length_m / 2.0


def centre_y(sumo_index, lateral_offset_m, lane_width_m):
    """The protocol's y of a vehicle's centre: SUMO lane k has its centre at k * width."""
    return sumo_index * lane_width_m + lateral_offset_m


def sv_observation(protocol_id, v, lane_width_m):
    """One SV of a request from its subscribed variables (a dict keyed by traci constants)."""
    length = v[tc.VAR_LENGTH]
    return {
        "id": protocol_id,
        "x_m": centre_x(v[tc.VAR_LANEPOSITION], length),
        "y_m": centre_y(v[tc.VAR_LANE_INDEX], v[tc.VAR_LANEPOSITION_LAT], lane_width_m),
        # SUMO never reports a negative speed, but a reversing vehicle would be rejected.
        "v_mps": max(0.0, v[tc.VAR_SPEED]),
        "a_mps2": v[tc.VAR_ACCELERATION],
        "vy_mps": v[tc.VAR_SPEED_LAT],
        "length_m": length,
        "width_m": v[tc.VAR_WIDTH],
    }


class SvIds:
    """Protocol ids (u32, stable for a vehicle's whole episode) for SUMO's string ids.

    The planner's memory names SVs by id, so an SV must keep its id from request to request.
    """

    def __init__(self):
        self._ids = {}

    def id_of(self, sumo_id):
        if sumo_id not in self._ids:
            self._ids[sumo_id] = len(self._ids) + 1
        return self._ids[sumo_id]

    def sumo_id_of(self, protocol_id):
        for k, v in self._ids.items():
            if v == protocol_id:
                return k
        return None


def road(lanes, lane_width_m, speed_limit_mps):
    return {"lanes": lanes, "lane_width_m": lane_width_m, "speed_limit_mps": speed_limit_mps}


def plan_request(
    *,
    vehicle_id,
    sequence,
    time_s,
    road_,
    ego_id,
    context,
    desired_speed_mps,
    maneuver,
    memory,
    sv_ids,
    range_ahead_m=200.0,
    range_behind_m=100.0,
):
    """The PlanRequest (a JSON dict) of one snapshot.

    `context` is the ego's context subscription result: {sumo id: {variable: value}}, the ego
    included. `maneuver` is the maneuver last commanded (the previous answer's next_maneuver),
    `memory` the previous answer's memory, sent back unchanged.
    """
    lanes, width = road_["lanes"], road_["lane_width_m"]
    e = context[ego_id]
    ego_x = centre_x(e[tc.VAR_LANEPOSITION], e[tc.VAR_LENGTH])
    svs = []
    for sumo_id, v in context.items():
        if sumo_id == ego_id:
            continue
        sv = sv_observation(sv_ids.id_of(sumo_id), v, width)
        if -range_behind_m <= sv["x_m"] - ego_x <= range_ahead_m:
            svs.append(sv)
    # The nearest MAX_SVS (the planner keeps the nearest perception.max_svs of those).
    svs.sort(key=lambda s: (abs(s["x_m"] - ego_x), s["id"]))
    svs = sorted(svs[:MAX_SVS], key=lambda s: s["id"])
    return {
        "version": PROTOCOL_VERSION,
        "vehicle_id": vehicle_id,
        "sequence": sequence,
        "timestamp_ns": int(round(time_s * 1e9)),
        "road": road_,
        "ego": {
            "x_m": ego_x,
            "y_m": centre_y(e[tc.VAR_LANE_INDEX], e[tc.VAR_LANEPOSITION_LAT], width),
            "v_mps": max(0.0, e[tc.VAR_SPEED]),
            "desired_speed_mps": desired_speed_mps,
            "maneuver": {"lane": maneuver["lane"], "beta": maneuver["beta"]},
        },
        "svs": svs,
        "memory": memory,
    }


def initial_maneuver(ego_sumo_index, lanes):
    """The maneuver before the first answer: keep the current lane, cruising."""
    return {"lane": protocol_lane(ego_sumo_index, lanes), "beta": 0}


def empty_memory():
    return {"corrective": [], "previous_plan": []}
