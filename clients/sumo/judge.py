"""SUMO as the judge: its collision detection and its SSM device, read from its own outputs.

Collisions: `--collision.action warn` (vehicles drive on, SUMO reports), with
`--collision.mingap-factor 0` (a collision is a physical overlap, not a gap below minGap);
read through TraCI every step and from SUMO's `--collision-output` file.

SSM: the device on the ego alone (`--device.ssm.explicit ego`) with trajectories, so that
the share of time with a TTC below 3 s can be computed; measures TTC, DRAC, PET and the time
gap to the leader (TGAP, the time headway).
"""

import math
import xml.etree.ElementTree as ET

from scenario import EGO_ID

# TTC below which a time step counts as critical (the share reported in the table).
TTC_CRITICAL_S = 3.0
# SSM thresholds: an encounter is written when one of its measures passes one of them. TTC is
# logged up to 10 s so that the minimum TTC is a real value in calm traffic too.
SSM_MEASURES = "TTC DRAC PET TGAP"
SSM_THRESHOLDS = "10.0 3.0 2.0 1.0"
SSM_RANGE_M = 100.0


def sumo_judge_options(ssm_file, collision_file):
    return [
        "--collision.action", "warn",
        "--collision.mingap-factor", "0",
        "--collision-output", collision_file,
        "--device.ssm.explicit", EGO_ID,
        "--device.ssm.measures", SSM_MEASURES,
        "--device.ssm.thresholds", SSM_THRESHOLDS,
        "--device.ssm.trajectories", "true",
        "--device.ssm.range", str(SSM_RANGE_M),
        "--device.ssm.file", ssm_file,
    ]  # fmt: skip


def _values(element):
    return element.get("values", "").split() if element is not None else []


def _number(text):
    try:
        x = float(text)
    except (TypeError, ValueError):
        return None  # "NA"
    return x if math.isfinite(x) else None


def parse_ssm(path, ego_id=EGO_ID):
    """The SSM figures of one episode from SUMO's SSM XML.

    Returns min_ttc_s, max_drac_mps2, min_pet_s, min_time_headway_s (None when SUMO logged no
    value), conflicts (encounters written), and ttc_critical_times (the set of time steps at
    which some encounter had a TTC below TTC_CRITICAL_S).
    """
    min_ttc = max_drac = min_pet = min_tgap = None
    conflicts = 0
    critical = set()
    for _, el in ET.iterparse(path, events=("end",)):
        if el.tag == "conflict" and el.get("ego") == ego_id:
            conflicts += 1
            times = _values(el.find("timeSpan"))
            ttcs = _values(el.find("TTCSpan"))
            for t, ttc in zip(times, ttcs):
                v = _number(ttc)
                if v is not None and v < TTC_CRITICAL_S:
                    critical.add(round(float(t), 3))
            for tag, attr in (("minTTC", "min_ttc"), ("maxDRAC", "max_drac"), ("PET", "min_pet")):
                node = el.find(tag)
                v = _number(node.get("value")) if node is not None else None
                if v is None:
                    continue
                if attr == "min_ttc":
                    min_ttc = v if min_ttc is None else min(min_ttc, v)
                elif attr == "max_drac":
                    max_drac = v if max_drac is None else max(max_drac, v)
                else:
                    min_pet = v if min_pet is None else min(min_pet, v)
            el.clear()
        elif el.tag == "globalMeasures" and el.get("ego") == ego_id:
            node = el.find("minTGAP")
            v = _number(node.get("value")) if node is not None else None
            if v is not None:
                min_tgap = v if min_tgap is None else min(min_tgap, v)
            el.clear()
    return {
        "min_ttc_s": min_ttc,
        "max_drac_mps2": max_drac,
        "min_pet_s": min_pet,
        "min_time_headway_s": min_tgap,
        "conflicts": conflicts,
        "ttc_critical_times": critical,
    }


def parse_collisions(path, ego_id=EGO_ID):
    """Collisions SUMO wrote to its collision output: (involving the ego, between others).

    SUMO writes a collision once per step while the vehicles overlap: a pair counts once.
    """
    ego_pairs, other_pairs = set(), set()
    for _, el in ET.iterparse(path, events=("end",)):
        if el.tag == "collision":
            pair = tuple(sorted((el.get("collider"), el.get("victim"))))
            (ego_pairs if ego_id in pair else other_pairs).add(pair)
            el.clear()
    return {"ego": len(ego_pairs), "others": len(other_pairs), "ego_pairs": sorted(ego_pairs)}


class CollisionWatch:
    """Collisions read from TraCI (`simulation.getCollisions`) step by step."""

    def __init__(self, ego_id=EGO_ID):
        self.ego_id = ego_id
        self.ego_pairs = {}  # pair -> first time
        self.other_pairs = set()

    def observe(self, collisions, time_s):
        """Returns True when the ego collided for the first time with someone in this step."""
        new_ego = False
        for c in collisions:
            pair = tuple(sorted((c.collider, c.victim)))
            if self.ego_id in pair:
                if pair not in self.ego_pairs:
                    self.ego_pairs[pair] = {"time_s": time_s, "collider": c.collider, "victim": c.victim, "type": c.type}
                    new_ego = True
            else:
                self.other_pairs.add(pair)
        return new_ego
