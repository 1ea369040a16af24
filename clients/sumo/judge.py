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
# SSM thresholds: an encounter is written when one of its measures passes its threshold at
# some step. TTC is logged up to 10 s and DRAC from 1 m/s^2, so that the minimum TTC and the
# maximum DRAC are real values in calm traffic too (a summary without any says so).
SSM_MEASURES = "TTC DRAC PET TGAP"
SSM_THRESHOLDS = "10.0 1.0 2.0 1.0"
SSM_TTC_LOGGED_BELOW_S = 10.0
SSM_DRAC_LOGGED_ABOVE_MPS2 = 1.0
SSM_RANGE_M = 100.0
# The first seconds after the ego's entry are SUMO's insertion (it inserts at the largest safe
# speed, often a short headway), not the driver's doing: the SSM figures start after them.
# Collisions count from the entry on.
SETTLE_S = 5.0


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


def _series(el, tag, from_s):
    """(time, value) of a span of `el` from `from_s` on, NA values left out."""
    times = _values(el.find("timeSpan"))
    out = []
    for t, x in zip(times, _values(el.find(tag))):
        t, v = float(t), _number(x)
        if v is not None and t >= from_s - 1e-6:
            out.append((t, v))
    return out


def parse_ssm(path, from_s=0.0, ego_id=EGO_ID):
    """The SSM figures of one episode from SUMO's SSM XML (its trajectories), from `from_s` on.

    Returns min_ttc_s, max_drac_mps2, min_pet_s, min_time_headway_s (None when SUMO logged no
    value), conflicts (encounters with a value after from_s), and ttc_critical_times (the set
    of time steps at which some encounter had a TTC below TTC_CRITICAL_S).
    """
    min_ttc = max_drac = min_pet = min_tgap = None
    conflicts = 0
    critical = set()
    for _, el in ET.iterparse(path, events=("end",)):
        if el.tag == "conflict" and el.get("ego") == ego_id:
            ttc = _series(el, "TTCSpan", from_s)
            drac = _series(el, "DRACSpan", from_s)
            pet = el.find("PET")
            pet_v = _number(pet.get("value")) if pet is not None else None
            pet_t = _number(pet.get("time")) if pet is not None else None
            if pet_v is not None and (pet_t is None or pet_t < from_s - 1e-6):
                pet_v = None
            if ttc or drac or pet_v is not None:
                conflicts += 1
            critical.update(round(t, 3) for t, v in ttc if v < TTC_CRITICAL_S)
            if ttc:
                m = min(v for _, v in ttc)
                min_ttc = m if min_ttc is None else min(min_ttc, m)
            if drac:
                m = max(v for _, v in drac)
                max_drac = m if max_drac is None else max(max_drac, m)
            if pet_v is not None:
                min_pet = pet_v if min_pet is None else min(min_pet, pet_v)
            el.clear()
        elif el.tag == "globalMeasures" and el.get("ego") == ego_id:
            tgap = _series(el, "TGAPSpan", from_s)
            if tgap:
                m = min(v for _, v in tgap)
                min_tgap = m if min_tgap is None else min(min_tgap, m)
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
