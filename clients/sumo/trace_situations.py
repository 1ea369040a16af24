#!/usr/bin/env python3
"""Situations from the bridge's traces, for `decision`'s `explain_decision` example.

    python3 clients/sumo/trace_situations.py --scenario clients/sumo/scenarios/3lanes-medium.toml \\
        --max-accel -3 OUT_DIR/3lanes-medium/planner/episode-*/trace.jsonl > hard.jsonl
    cargo run --release -p decision --example explain_decision -- hard.jsonl

Selects the decisions whose set-point accelerates at most --max-accel (default: every one)
and writes one JSON object per line: where it was, the answer's acceleration, the situation
the planner was asked (road, ego, SVs, memory).
"""
import argparse
import json
import os
import sys

from scenario import load_scenario


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", required=True, help="the episodes' scenario file (for the road)")
    parser.add_argument("--max-accel", type=float, default=float("inf"), help="m/s^2")
    parser.add_argument("traces", nargs="+")
    args = parser.parse_args()
    s = load_scenario(args.scenario)
    road = {"lanes": s.lanes, "lane_width_m": s.lane_width_m, "speed_limit_mps": s.speed_limit_mps}
    for path in args.traces:
        episode = os.path.basename(os.path.dirname(path))
        with open(path) as f:
            for line in f:
                r = json.loads(line)
                accel = (r.get("setpoint") or {}).get("accel_mps2")
                if accel is None or accel > args.max_accel:
                    continue
                situation = {"road": road, "ego": r["ego_sent"], "svs": r["svs_sent"], "memory": r["memory_sent"]}
                where = f"{episode} t={r['time_s']:.1f}"
                sys.stdout.write(json.dumps({"where": where, "accel": accel, "situation": situation}) + "\n")


if __name__ == "__main__":
    main()
