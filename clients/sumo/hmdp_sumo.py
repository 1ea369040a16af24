#!/usr/bin/env python3
"""Co-simulation with SUMO: the HMDP planner drives a SUMO vehicle, and SUMO judges it.

    python3 clients/sumo/hmdp_sumo.py --spawn-planner --scenario clients/sumo/scenarios/3lanes-medium.toml \\
        --episodes 20 --json results.json
    python3 clients/sumo/hmdp_sumo.py --zenoh-connect tcp/127.0.0.1:7447 --scenario FILE --episodes 2 --gui

Each episode runs the scenario (seed = the scenario's seed + episode) once per driver: the
planner (over Zenoh, through TraCI, see control.py), and SUMO's own ego models, Krauss +
LC2013 and IDM + LC2013, as baselines. SUMO counts the collisions and its SSM device measures
the ego's conflicts. Prints a markdown table per scenario; `--json` writes everything.

Exit code: 0 all episodes ran, 1 an episode could not be run (no planner, a rejection, a
bad scenario), 2 a bad command line.
"""

import argparse
import json
import os
import sys
import tempfile
import time

import control
import paired
import planner_link
import report
import scenario as scenarios

LABELS = {"planner": paired.PLANNER, "krauss": "SUMO Krauss + LC2013", "idm": "SUMO IDM + LC2013"}


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    where = p.add_mutually_exclusive_group()
    where.add_argument("--spawn-planner", action="store_true", help="start a planner serve on a free loopback port")
    where.add_argument("--zenoh-connect", metavar="ENDPOINT", help="the planner's Zenoh endpoint, e.g. tcp/127.0.0.1:7447")
    p.add_argument("--scenario", action="append", required=True, metavar="FILE", help="scenario file (TOML); repeatable")
    p.add_argument("--episodes", type=int, default=1, help="seeded episodes per scenario and driver (default 1)")
    p.add_argument(
        "--drivers",
        default=",".join(scenarios.DRIVERS),
        help="comma-separated subset of planner,krauss,idm (default: all three)",
    )
    p.add_argument("--json", metavar="FILE", help="write the results (summaries and every episode) as JSON")
    p.add_argument("--markdown", metavar="FILE", help="also write the tables to FILE")
    p.add_argument("--out-dir", metavar="DIR", help="keep SUMO's files here (network, routes, SSM, collisions, traces)")
    p.add_argument("--gui", action="store_true", help="run sumo-gui, for a person to watch")
    p.add_argument("--planner-bin", metavar="PATH", help="planner binary for --spawn-planner (default: found in target/)")
    p.add_argument("--planner-config", metavar="FILE", help="--config for the spawned planner")
    p.add_argument("--planner-workers", type=int, default=1, help="--workers for the spawned planner (default 1)")
    p.add_argument(
        "--speed-split-s",
        type=float,
        default=control.SPEED_SPLIT_S,
        help="also compare the mean speed from this long after the ego's entry on (default 20)",
    )
    p.add_argument("--timeout", type=float, default=2.0, help="seconds to wait for each answer (default 2)")
    p.add_argument(
        "--planner-key",
        metavar="FILE.pub",
        help="the planner's public key (planner keygen): answers that do not verify are refused",
    )
    p.add_argument(
        "--insecure",
        action="store_true",
        help="without --planner-key, use a planner beyond this host anyway (its answers are not verified)",
    )
    args = p.parse_args(argv)
    args.drivers = [d.strip() for d in args.drivers.split(",") if d.strip()]
    for d in args.drivers:
        if d not in scenarios.DRIVERS:
            p.error(f"unknown driver {d!r}")
    if "planner" in args.drivers and not (args.spawn_planner or args.zenoh_connect):
        p.error("the planner driver needs --spawn-planner or --zenoh-connect")
    if args.episodes < 1:
        p.error("--episodes must be at least 1")
    if not args.speed_split_s >= 0.0:
        p.error("--speed-split-s must be a non-negative number")
    return args


def connect(args, out_dir):
    """(PlannerLink, SpawnedPlanner or None), or (None, None) without the planner driver."""
    if "planner" not in args.drivers:
        return None, None
    spawned = None
    endpoint = args.zenoh_connect
    if args.spawn_planner:
        binary = planner_link.find_planner(args.planner_bin)
        spawned = planner_link.SpawnedPlanner(
            binary, os.path.join(out_dir, "planner.log"), config=args.planner_config, workers=args.planner_workers
        )
        endpoint = spawned.endpoint
    verifier = planner_link.load_verifier(args.planner_key) if args.planner_key else None
    # A spawned planner listens on loopback and has no key: its answers stay unsigned.
    link = planner_link.PlannerLink(endpoint, timeout_s=args.timeout, verifier=verifier, insecure=args.insecure)
    alive = (lambda: spawned.process.poll() is None) if spawned else (lambda: True)
    link.wait_ready(alive=alive)
    return link, spawned


def run(args, out_dir):
    results = {"drivers": args.drivers, "scenarios": []}
    link, spawned = connect(args, out_dir)
    try:
        for path in args.scenario:
            s = scenarios.load_scenario(path)
            s_dir = os.path.join(out_dir, s.name)
            os.makedirs(s_dir, exist_ok=True)
            net = scenarios.write_network(s, s_dir)
            episodes = {d: [] for d in args.drivers}
            for driver in args.drivers:
                routes = scenarios.write_routes(s, driver, s_dir)
                for episode in range(args.episodes):
                    started = time.monotonic()
                    ep_dir = os.path.join(s_dir, driver, f"episode-{episode:03d}")
                    metrics = control.run_episode(
                        s, driver, episode, net, routes, ep_dir, link=link, gui=args.gui, speed_split_s=args.speed_split_s
                    )
                    metrics["wall_s"] = time.monotonic() - started
                    episodes[driver].append(metrics)
                    print(
                        f"{s.name} {driver} episode {episode}: {metrics['collisions']} collisions, "
                        f"{metrics['mean_speed_mps']:.2f} m/s, {metrics['wall_s']:.1f} s",
                        file=sys.stderr,
                    )
            entry = {
                "scenario": scenario_dict(s, path),
                "episodes": args.episodes,
                "drivers": {LABELS[d]: report.summarise(episodes[d]) for d in args.drivers},
                "episode_metrics": {LABELS[d]: [slim(e) for e in episodes[d]] for d in args.drivers},
            }
            if "planner" in args.drivers and len(args.drivers) > 1:
                labelled = {LABELS[d]: episodes[d] for d in args.drivers}
                entry["paired_speed"] = report.paired_speed_entry(labelled, LABELS["planner"])
            results["scenarios"].append(entry)
    finally:
        if link:
            if link.refused:
                print(f"hmdp_sumo: refused {len(link.refused)} answers that did not verify: {link.refused[-1]}", file=sys.stderr)
            link.close()
        if spawned:
            spawned.stop()
    return results


def scenario_dict(s, path):
    d = {k: getattr(s, k) for k in s.__dataclass_fields__ if k != "traffic"}
    d["traffic"] = [t.__dict__ for t in s.traffic]
    d["file"] = path
    return d


def slim(e):
    """An episode's metrics without the raw round trips (their percentiles instead)."""
    e = dict(e)
    rtts = e.pop("round_trips_s")
    e["round_trip_p50_ms"] = report.percentile(rtts, 50) * 1e3 if rtts else None
    e["round_trip_p99_ms"] = report.percentile(rtts, 99) * 1e3 if rtts else None
    return e


def main(argv=None):
    args = parse_args(argv if argv is not None else sys.argv[1:])
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="hmdp-sumo-") as tmp:
        out_dir = os.path.abspath(args.out_dir) if args.out_dir else tmp
        os.makedirs(out_dir, exist_ok=True)
        try:
            results = run(args, out_dir)
        except (control.BridgeError, planner_link.NoAnswer, planner_link.BadInput, FileNotFoundError, ValueError) as e:
            print(f"hmdp_sumo: {e}", file=sys.stderr)
            return 1
    results["wall_s"] = time.monotonic() - started
    table = report.markdown(results)
    print(table)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(table + "\n")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
