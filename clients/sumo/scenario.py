"""Scenarios: a scenario file (TOML) and the SUMO network and routes generated from it.

Nothing is downloaded: the straight highway is built by netconvert from two nodes and one
edge, the traffic is a set of SUMO flows with Poisson departures over a mix of vehicle types
(Krauss and IDM car following, LC2013 lane changing), all drawn from SUMO's random stream, so
that one seed gives one traffic.
"""

import dataclasses
import os
import subprocess
import tomllib
from xml.sax.saxutils import quoteattr

import sumolib

# The ego's SUMO vehicle id and the id of the single highway edge.
EGO_ID = "ego"
EDGE_ID = "highway"

# The drivers an episode can have for its ego: the planner, or SUMO's own models.
DRIVERS = ("planner", "krauss", "idm")


@dataclasses.dataclass(frozen=True)
class VehicleType:
    """One class of surrounding traffic (a SUMO vType)."""

    id: str
    share: float  # share of the flow
    car_follow_model: str = "Krauss"  # Krauss or IDM
    sigma: float = 0.5  # driver imperfection (Krauss; SUMO's IDM ignores it)
    tau_s: float = 1.0  # desired time headway
    accel_mps2: float = 2.6
    decel_mps2: float = 4.5
    length_m: float = 5.0
    width_m: float = 1.8
    max_speed_mps: float = 55.0  # the vehicle's own limit; the road's limit applies too
    speed_factor: str = "normc(1.0,0.1,0.2,2.0)"  # SUMO distribution of the speed factor
    lc_speed_gain: float = 1.0  # LC2013 lcSpeedGain
    lc_keep_right: float = 1.0  # LC2013 lcKeepRight


# The default traffic: mostly Krauss drivers (some imperfect), IDM drivers, a few trucks.
DEFAULT_TRAFFIC = (
    VehicleType("krauss_car", 0.4, "Krauss", sigma=0.5),
    VehicleType("krauss_calm", 0.15, "Krauss", sigma=0.0),
    VehicleType("idm_car", 0.3, "IDM", sigma=0.0, accel_mps2=1.5, decel_mps2=2.0),
    VehicleType(
        "truck",
        0.15,
        "Krauss",
        sigma=0.3,
        accel_mps2=1.0,
        decel_mps2=4.0,
        length_m=12.0,
        width_m=2.5,
        max_speed_mps=25.0,
        speed_factor="normc(1.0,0.05,0.8,1.2)",
    ),
)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """What one scenario file selects (lanes, density, speed mix, duration, seed)."""

    name: str
    lanes: int = 3
    lane_width_m: float = 3.5
    length_m: float = 3500.0
    speed_limit_mps: float = 33.33
    flow_veh_per_hour_per_lane: float = 1200.0
    warmup_s: float = 120.0  # traffic fills the road before the ego enters
    duration_s: float = 60.0  # from the ego's entry
    seed: int = 1  # episode i runs with seed + i
    ego_lane: int = 2  # protocol numbering: 1 = leftmost
    ego_depart_pos_m: float = 300.0  # front of the ego at entry, from the road's start
    ego_desired_speed_mps: float = 33.33
    ego_accel_mps2: float = 2.6  # SUMO's egos' maximum acceleration (SUMO's default); the planner's is its own
    traffic: tuple = DEFAULT_TRAFFIC

    def episode_seed(self, episode):
        return self.seed + episode


def load_scenario(path):
    """Reads a scenario file; unknown keys are an error (a typo must not pass silently)."""
    with open(path, "rb") as f:
        data = tomllib.load(f)
    data.setdefault("name", os.path.splitext(os.path.basename(path))[0])
    traffic = data.pop("traffic", None)
    known = {f.name for f in dataclasses.fields(Scenario)}
    unknown = set(data) - known
    if unknown:
        raise ValueError(f"{path}: unknown keys {sorted(unknown)}")
    if traffic is not None:
        vtype_known = {f.name for f in dataclasses.fields(VehicleType)}
        for t in traffic:
            if set(t) - vtype_known:
                raise ValueError(f"{path}: unknown traffic keys {sorted(set(t) - vtype_known)}")
        data["traffic"] = tuple(VehicleType(**t) for t in traffic)
    scenario = Scenario(**data)
    check_scenario(scenario)
    return scenario


def check_scenario(s):
    if not 2 <= s.lanes <= 8:
        raise ValueError(f"lanes must be 2..8, got {s.lanes}")
    if not 1 <= s.ego_lane <= s.lanes:
        raise ValueError(f"ego_lane must be 1..{s.lanes} (1 = leftmost), got {s.ego_lane}")
    # The ego must not reach the road's end within the episode (it would leave SUMO).
    reach = s.ego_depart_pos_m + s.duration_s * max(s.speed_limit_mps, s.ego_desired_speed_mps) * 1.1
    if reach + 200.0 > s.length_m:
        raise ValueError(f"length_m {s.length_m} too short for a {s.duration_s} s episode (needs {reach + 200.0:.0f})")
    if not s.ego_accel_mps2 > 0.0:
        raise ValueError(f"ego_accel_mps2 must be positive, got {s.ego_accel_mps2}")
    if abs(sum(t.share for t in s.traffic) - 1.0) > 1e-6:
        raise ValueError("traffic shares must sum to 1")


def write_network(scenario, directory):
    """The straight highway, along +x from x = 0, built by netconvert; returns its path."""
    nodes = os.path.join(directory, "highway.nod.xml")
    edges = os.path.join(directory, "highway.edg.xml")
    net = os.path.join(directory, "highway.net.xml")
    with open(nodes, "w") as f:
        f.write(f'<nodes>\n  <node id="start" x="0" y="0"/>\n  <node id="end" x="{scenario.length_m}" y="0"/>\n</nodes>\n')
    with open(edges, "w") as f:
        f.write(
            f'<edges>\n  <edge id="{EDGE_ID}" from="start" to="end" numLanes="{scenario.lanes}" '
            f'speed="{scenario.speed_limit_mps}" width="{scenario.lane_width_m}"/>\n</edges>\n'
        )
    subprocess.run(
        ["netconvert", "--node-files", nodes, "--edge-files", edges, "--output-file", net, "--no-turnarounds", "true"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    # What netconvert built is what the mapping assumes: the lanes, their width, straight along +x.
    edge = sumolib.net.readNet(net).getEdge(EDGE_ID)
    lanes = edge.getLanes()
    if len(lanes) != scenario.lanes or any(abs(lane.getWidth() - scenario.lane_width_m) > 1e-6 for lane in lanes):
        raise ValueError(f"netconvert built {len(lanes)} lanes, not {scenario.lanes} of {scenario.lane_width_m} m")
    if any(abs(y - lanes[0].getShape()[0][1]) > 1e-6 for _, y in lanes[0].getShape()):
        raise ValueError("netconvert did not build a straight road along +x")
    return net


def vtype_xml(t):
    return (
        f'  <vType id={quoteattr(t.id)} carFollowModel="{t.car_follow_model}" laneChangeModel="LC2013" '
        f'sigma="{t.sigma}" tau="{t.tau_s}" accel="{t.accel_mps2}" decel="{t.decel_mps2}" '
        f'length="{t.length_m}" width="{t.width_m}" maxSpeed="{t.max_speed_mps}" '
        f'speedFactor="{t.speed_factor}" lcSpeedGain="{t.lc_speed_gain}" lcKeepRight="{t.lc_keep_right}"/>\n'
    )


def ego_vtype(scenario, driver):
    """The ego's vType for a driver. Same size and desired speed for every driver.

    SUMO's own egos are deterministic (sigma 0) so that they are the strongest form of their
    model; the planner's ego has the planner's vehicle size (5 m x 2 m) and its car-following
    model is never consulted (speed mode 0, see control.py).
    """
    if driver not in DRIVERS:
        raise ValueError(f"unknown driver {driver}")
    model = {"planner": "Krauss", "krauss": "Krauss", "idm": "IDM"}[driver]
    return VehicleType(
        id=f"ego_{driver}",
        share=0.0,
        car_follow_model=model,
        sigma=0.0,
        length_m=5.0,
        width_m=2.0,
        # SUMO's egos: the desired speed is the vehicle's own limit (speed factor 1). The
        # planner's: its desired speed goes into the request, and SUMO must not cap its commands.
        max_speed_mps=55.0 if driver == "planner" else scenario.ego_desired_speed_mps,
        speed_factor="1",
        accel_mps2=scenario.ego_accel_mps2,
    )


def write_routes(scenario, driver, directory):
    """The flows (one per lane and type, Poisson departures) and the ego; returns the path."""
    path = os.path.join(directory, f"traffic-{driver}.rou.xml")
    ego = ego_vtype(scenario, driver)
    parts = ["<routes>\n"]
    parts += [vtype_xml(t) for t in scenario.traffic]
    parts.append(vtype_xml(ego))
    parts.append(f'  <route id="through" edges="{EDGE_ID}"/>\n')
    flows = []
    for lane in range(scenario.lanes):
        for t in scenario.traffic:
            rate = scenario.flow_veh_per_hour_per_lane * t.share / 3600.0
            if rate <= 0:
                continue
            # period="exp(rate)": exponential headways (Poisson arrivals) from SUMO's seeded stream.
            flows.append(
                f'  <flow id="{t.id}_l{lane}" type="{t.id}" route="through" begin="0" end="{scenario.warmup_s + scenario.duration_s + 60}" '
                f'period="exp({rate:.6f})" departLane="{lane}" departPos="base" departSpeed="max"/>\n'
            )
    parts += flows
    # After the flows: a route file is read in order of departure, and the ego leaves at warmup_s.
    sumo_lane = scenario.lanes - scenario.ego_lane  # protocol 1 = leftmost, SUMO 0 = rightmost
    parts.append(
        f'  <vehicle id="{EGO_ID}" type="{ego.id}" route="through" depart="{scenario.warmup_s}" '
        f'departLane="{sumo_lane}" departPos="{scenario.ego_depart_pos_m}" departSpeed="max"/>\n'
    )
    parts.append("</routes>\n")
    with open(path, "w") as f:
        f.write("".join(parts))
    return path
