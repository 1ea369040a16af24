#!/usr/bin/env python3
"""Recomputes a campaign's figures from its trials.jsonl and checks them against its
results.json: an oracle for `sim_client`'s aggregation written from the definitions in
docs/safety-metrics.md, not from the Rust code. Standard library only.

    python3 clients/campaign_check/check_trials.py OUT_DIR

OUT_DIR is a campaign's `--out` directory (it holds campaign/trials.jsonl and
campaign/results.json). Prints one line per row checked; exits 1 on the first mismatch.
"""

import json
import math
import sys
from pathlib import Path

REL_TOL = 1e-9


def nearest_rank(values, p):
    """Nearest-rank percentile; an episode that never closed in counts as infinite."""
    v = sorted(math.inf if x is None else x for x in values)
    rank = min(max(math.ceil(p * len(v)), 1), len(v))
    x = v[rank - 1]
    return None if math.isinf(x) else x


def figures(trials):
    """The figures of one group of trials, from their per-trial metrics."""
    m = [t["metrics"] for t in trials]
    dt = trials[0]["dt_s"]
    simulated = sum(x["simulated_s"] for x in m)
    steps = sum(x["safety"]["steps"] for x in m)
    layers, split = {}, {}
    for x in m:
        for k, n in x["decisions_by_layer"].items():
            layers[k] = layers.get(k, 0) + n
        for k, n in x["nominal_split"].items():
            split[k] = split.get(k, 0) + n
    # The shares are of everything counted, rejections included.
    total = sum(layers.values())
    planner = trials[0]["driver"] != "idm_mobil"
    minutes = simulated / 60.0
    hours = steps * dt / 3600.0
    ratio = lambda a, b: a / b if b else 0.0
    return {
        "trials": len(trials),
        "decisions": sum(x["decisions"] for x in m),
        "collisions": sum(x["collisions"] for x in m),
        "mean_speed_mps": ratio(sum(x["mean_speed_mps"] * x["simulated_s"] for x in m), simulated),
        "beta_switches_per_min": ratio(sum(x["beta_switches"] for x in m), minutes),
        "lane_changes_per_min": ratio(sum(x["lane_changes"] for x in m), minutes),
        "nor": ratio(layers.get("nominal", 0), total) if planner else None,
        # The plain MPC's share: plain, or relaxed by choice where the plain MPC had a plan too.
        "plain_nor": ratio(split.get("plain", 0) + split.get("relaxed_by_choice", 0), total) if planner else None,
        "gsrr": ratio(layers.get("global_relaxation", 0), total) if planner else None,
        "fbr": ratio(layers.get("fallback", 0), total) if planner else None,
        "safety.min_ttc_min_s": nearest_rank([x["safety"]["min_ttc_s"] for x in m], 0.0),
        "safety.min_ttc_p5_s": nearest_rank([x["safety"]["min_ttc_s"] for x in m], 0.05),
        "safety.min_ttc_p50_s": nearest_rank([x["safety"]["min_ttc_s"] for x in m], 0.5),
        "safety.ttc_below_3s_share": ratio(sum(x["safety"]["ttc_below_3s_steps"] for x in m), steps),
        "safety.headway_below_1s_share": ratio(
            sum(x["safety"]["headway_below_1s_steps"] for x in m), steps
        ),
        "safety.hard_braking_per_hour": ratio(sum(x["safety"]["hard_braking_events"] for x in m), hours),
        "safety.max_drac_mps2": max(x["safety"]["max_drac_mps2"] for x in m),
    }


def reported(row, key):
    for part in key.split("."):
        row = row[part]
    return row


def same(a, b):
    if a is None or b is None:
        return a is None and b is None
    return math.isclose(a, b, rel_tol=REL_TOL, abs_tol=1e-12)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = Path(sys.argv[1]) / "campaign"
    trials = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines() if line]
    results = json.loads((out / "results.json").read_text())
    rows = [(g, [t for t in trials if t["driver"] == g["driver"] and g["config_id"] in (None, t["config_id"])])
            for g in results["groups"] + results["overall"]]
    for row, group in rows:
        if not group:
            sys.exit(f"no trials for {row['driver']} configuration {row['config_id']}")
        for key, value in figures(group).items():
            if not same(value, reported(row, key)):
                sys.exit(
                    f"MISMATCH {row['driver']} configuration {row['config_id']}: {key} "
                    f"recomputed {value}, reported {reported(row, key)}"
                )
        print(f"ok {row['driver']} configuration {row['config_id']}: {len(group)} trials")
    print(f"all {len(rows)} rows agree")


if __name__ == "__main__":
    main()
