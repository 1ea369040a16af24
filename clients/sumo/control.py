"""One episode in SUMO: the ego driven by the planner (through TraCI) or by SUMO's own models.

Taking over the ego (driver "planner"):

* speed mode 0: SUMO applies the commanded acceleration as is; none of its checks (safe
  speed, maximum acceleration and deceleration) overrides the planner;
* lane-change mode 0: SUMO makes no lane change of its own (strategic, cooperative, speed
  gain, keep right all off) and executes a TraCI lane change without checking the gaps,
  so the planner's lateral decision is applied as decided;
* every 0.4 s (the planner's period, timing.step_s): a context subscription gives the ego's
  surroundings, mapped to a PlanRequest (mapping.py); the answer is applied at once: a new
  target lane through `changeLane` (3 s, with SUMO's `--lanechange.duration 3`, the planner's
  ego.lane_change_s, so the manoeuvre takes as long as the planner assumes), the
  longitudinal set-point through `setAcceleration(accel_mps2, 0.4 s)`: the plan's first-step
  acceleration held for the period, which ends at the set-point's target speed.

SUMO waits for each answer (the simulation is stepped by the bridge): the planner's round
trip is measured but costs no simulated time.
"""

import contextlib
import io
import json
import os
import shutil

import traci
import traci.constants as tc

import judge
import mapping
from scenario import EDGE_ID, EGO_ID

STEP_LENGTH_S = 0.1
DECISION_PERIOD_S = 0.4  # deploy/planner.toml timing.step_s
LANE_CHANGE_S = 3.0  # deploy/planner.toml ego.lane_change_s
CONTEXT_RANGE_M = 200.0  # perception.range_ahead_m; the request keeps 100 m behind
SPEED_MODE_PLANNER = 0
LANE_CHANGE_MODE_PLANNER = 0
VEHICLE_ID = 1  # the request's vehicle_id
# The mean speed is also given from this long after the ego's entry on: SUMO inserts the ego
# at its largest safe speed, often at a short headway, and the first seconds are a driver's
# answer to that insertion (the gap it opens), not its steady driving.
SPEED_SPLIT_S = 20.0


class BridgeError(Exception):
    """The episode could not be run as specified (no answer, a rejection, the ego never entered)."""


def sumo_binary(gui=False):
    name = "sumo-gui" if gui else "sumo"
    try:
        import sumo  # eclipse-sumo: the binaries are in the package

        path = os.path.join(sumo.SUMO_HOME, "bin", name)
        if os.access(path, os.X_OK):
            return path
    except ImportError:
        pass
    found = shutil.which(name)
    if not found:
        raise BridgeError(f"{name} not found: pip install -r clients/sumo/requirements.txt")
    return found


def sumo_command(scenario, net, routes, seed, directory, gui=False):
    end = scenario.warmup_s + scenario.duration_s + 30.0
    command = [
        sumo_binary(gui),
        "--net-file", net,
        "--route-files", routes,
        "--seed", str(seed),
        "--step-length", str(STEP_LENGTH_S),
        "--begin", "0",
        "--end", str(end),
        "--lanechange.duration", str(LANE_CHANGE_S),
        "--time-to-teleport", "-1",  # a jam never teleports a vehicle away
        # Each waiting vehicle is tried on its own: the ego (entering mid-road) does not wait
        # behind a queue of flow vehicles that cannot enter at the road's start.
        "--eager-insert", "true",
        "--no-step-log", "true",
        "--error-log", os.path.join(directory, "sumo-warnings.log"),
        # The ego's own trajectory as SUMO records it (lane, position, speed every step).
        "--device.fcd.explicit", EGO_ID,
        "--fcd-output", os.path.join(directory, "ego-fcd.xml"),
    ]  # fmt: skip
    command += judge.sumo_judge_options(os.path.join(directory, "ssm.xml"), os.path.join(directory, "collisions.xml"))
    if gui:
        command += ["--start", "--quit-on-end", "--delay", "50"]
    return command


def _start(command):
    # traci prints its connection retries on stdout; they are not the bridge's output.
    with contextlib.redirect_stdout(io.StringIO()):
        traci.start(command)


def _wait_for_ego(scenario):
    """Steps until the ego is in the network (SUMO delays an insertion that has no room)."""
    give_up = scenario.warmup_s + 60.0
    while EGO_ID not in traci.vehicle.getIDList():
        if traci.simulation.getTime() > give_up:
            raise BridgeError(f"the ego could not enter the road within {give_up} s")
        traci.simulationStep()


class LateralCheck:
    """Whether each lane change the planner decided happened in SUMO (lane index reached)."""

    def __init__(self):
        self.pending = []  # (decision index, SUMO target lane, time issued)
        self.applied = 0
        self.decided = 0
        self.superseded = 0
        self.not_applied = []

    def issued(self, index, target, time_s):
        # A new target while a change is pending replaces it (it is not a failure of SUMO's).
        self.superseded += len(self.pending)
        self.pending = [(index, target, time_s)]
        self.decided += 1

    def observe(self, lane_index, time_s):
        still = []
        for index, target, issued_at in self.pending:
            if lane_index == target:
                self.applied += 1
            elif time_s - issued_at > LANE_CHANGE_S + 1.0:
                self.not_applied.append({"decision": index, "target_sumo_lane": target, "issued_s": issued_at})
            else:
                still.append((index, target, issued_at))
        self.pending = still

    def summary(self):
        return {
            "decided": self.decided,
            "applied": self.applied,
            "superseded": self.superseded,
            "in_progress_at_end": len(self.pending),
            "not_applied": self.not_applied,
        }


def run_episode(scenario, driver, episode, net, routes, directory, link=None, gui=False, speed_split_s=SPEED_SPLIT_S):
    """Runs one episode; returns its metrics (a dict) and writes SUMO's outputs to `directory`.

    Besides the mean speed of the whole episode, the mean speed from `speed_split_s` after the
    ego's entry on (None when the episode ends before).
    """
    os.makedirs(directory, exist_ok=True)
    seed = scenario.episode_seed(episode)
    _start(sumo_command(scenario, net, routes, seed, directory, gui))
    trace_path = os.path.join(directory, "trace.jsonl")
    try:
        _wait_for_ego(scenario)
        # The traffic the ego meets: vehicles per km and lane on the road when it enters.
        density = traci.edge.getLastStepVehicleNumber(EDGE_ID) / (scenario.length_m / 1000.0 * scenario.lanes)
        if driver == "planner":
            traci.vehicle.setSpeedMode(EGO_ID, SPEED_MODE_PLANNER)
            traci.vehicle.setLaneChangeMode(EGO_ID, LANE_CHANGE_MODE_PLANNER)
        traci.vehicle.subscribeContext(EGO_ID, tc.CMD_GET_VEHICLE_VARIABLE, CONTEXT_RANGE_M, mapping.VEHICLE_VARIABLES)
        with open(trace_path, "w") as trace:
            result = _drive(scenario, driver, link, trace, speed_split_s)
    finally:
        traci.close()  # SUMO writes its SSM and collision outputs when it closes
    ssm = judge.parse_ssm(os.path.join(directory, "ssm.xml"), from_s=result["entry_s"] + judge.SETTLE_S)
    collisions_file = judge.parse_collisions(os.path.join(directory, "collisions.xml"))
    critical = ssm.pop("ttc_critical_times")
    # The share is of the steps the SSM figures cover (after the settling time).
    steps = max(0, result["steps"] - round(judge.SETTLE_S / STEP_LENGTH_S))
    result.update(
        scenario=scenario.name,
        driver=driver,
        episode=episode,
        seed=seed,
        ssm=ssm,
        ssm_steps=steps,
        density_at_entry_veh_per_km_lane=density,
        entry_delay_s=result["entry_s"] - scenario.warmup_s,
        ttc_below_3s_share=len(critical) / steps if steps else 0.0,
        collisions_sumo_output=collisions_file,
    )
    return result


def _drive(scenario, driver, link, trace, speed_split_s):
    road = mapping.road(scenario.lanes, scenario.lane_width_m, scenario.speed_limit_mps)
    start_s = traci.simulation.getTime()
    end_s = start_s + scenario.duration_s
    steps_per_decision = round(DECISION_PERIOD_S / STEP_LENGTH_S)
    collisions = judge.CollisionWatch()
    lateral = LateralCheck()
    sv_ids = mapping.SvIds()
    ego = traci.vehicle.getContextSubscriptionResults(EGO_ID)[EGO_ID]
    maneuver = mapping.initial_maneuver(ego[tc.VAR_LANE_INDEX], scenario.lanes)
    memory = mapping.empty_memory()
    layers, round_trips = {}, []
    speed_sum, steps, lane_changes = 0.0, 0, 0
    late_speed_sum, late_steps = 0.0, 0
    last_lane = ego[tc.VAR_LANE_INDEX]
    speed_errors, pending_target_speed = [], None
    sequence = 0
    while traci.simulation.getTime() < end_s - 1e-9:
        context = traci.vehicle.getContextSubscriptionResults(EGO_ID)
        if EGO_ID not in context:
            raise BridgeError("the ego left the road before the episode's end")
        now = traci.simulation.getTime()
        if driver == "planner" and steps % steps_per_decision == 0:
            v_now = context[EGO_ID][tc.VAR_SPEED]
            if pending_target_speed is not None:
                # The last set-point's acceleration was held for a period: SUMO's speed must be its target.
                speed_errors.append(abs(v_now - max(0.0, pending_target_speed)))
            sequence += 1
            request = mapping.plan_request(
                vehicle_id=VEHICLE_ID,
                sequence=sequence,
                time_s=now,
                road_=road,
                ego_id=EGO_ID,
                context=context,
                desired_speed_mps=scenario.ego_desired_speed_mps,
                maneuver=maneuver,
                memory=memory,
                sv_ids=sv_ids,
            )
            response, rtt = link.decide(request)
            round_trips.append(rtt)
            outcome = response["outcome"]
            if "rejected" in outcome:
                raise BridgeError(f"the planner rejected request {sequence} at t={now:.1f} s: {outcome['rejected']}")
            decided = outcome["decided"]
            layers[decided["layer"]] = layers.get(decided["layer"], 0) + 1
            target = decided["next_maneuver"]
            if target["lane"] != maneuver["lane"]:
                sumo_target = mapping.sumo_lane_index(target["lane"], scenario.lanes)
                traci.vehicle.changeLane(EGO_ID, sumo_target, LANE_CHANGE_S)
                lateral.issued(sequence, sumo_target, now)
            setpoint = decided["setpoint"]
            traci.vehicle.setAcceleration(EGO_ID, setpoint["accel_mps2"], DECISION_PERIOD_S)
            pending_target_speed = setpoint["target_speed_mps"]
            trace.write(
                json.dumps(
                    {
                        "sequence": sequence,
                        "time_s": round(now, 3),
                        "ego_sumo_lane": context[EGO_ID][tc.VAR_LANE_INDEX],
                        "ego_v_mps": v_now,
                        "svs_sent": request["svs"],
                        "ego_sent": request["ego"],
                        "maneuver_sent": request["ego"]["maneuver"],
                        "memory_sent": request["memory"],
                        "layer": decided["layer"],
                        "action": decided["action"],
                        "next_maneuver": target,
                        "setpoint": setpoint,
                        "memory": decided["memory"],
                        "round_trip_s": rtt,
                    }
                )
                + "\n"
            )
            maneuver, memory = target, decided["memory"]
        traci.simulationStep()
        steps += 1
        now = traci.simulation.getTime()
        ego = traci.vehicle.getContextSubscriptionResults(EGO_ID).get(EGO_ID)
        if ego is None:
            raise BridgeError("the ego left the road before the episode's end")
        speed_sum += ego[tc.VAR_SPEED]
        if now - start_s > speed_split_s + 1e-9:
            late_speed_sum += ego[tc.VAR_SPEED]
            late_steps += 1
        if ego[tc.VAR_LANE_INDEX] != last_lane:
            lane_changes += 1
            last_lane = ego[tc.VAR_LANE_INDEX]
        lateral.observe(ego[tc.VAR_LANE_INDEX], now)
        if collisions.observe(traci.simulation.getCollisions(), now):
            break  # as in the project's simulator: an episode ends at the ego's first collision
    simulated = traci.simulation.getTime() - start_s
    return {
        "entry_s": start_s,
        "steps": steps,
        "simulated_s": simulated,
        "mean_speed_mps": speed_sum / steps if steps else 0.0,
        "speed_split_s": speed_split_s,
        "mean_speed_after_split_mps": late_speed_sum / late_steps if late_steps else None,
        "lane_changes": lane_changes,
        "lane_changes_per_min": lane_changes / (simulated / 60.0) if simulated > 0 else 0.0,
        "collisions": len(collisions.ego_pairs),
        "collision_events": list(collisions.ego_pairs.values()),
        "sv_collisions": len(collisions.other_pairs),
        "decisions": sequence,
        "layers": layers,
        "round_trips_s": round_trips,
        "lateral": lateral.summary() if driver == "planner" else None,
        "max_speed_error_mps": max(speed_errors) if speed_errors else None,
    }
