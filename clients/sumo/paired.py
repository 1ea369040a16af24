"""Paired comparison of two drivers over the same seeds.

Episode e of every driver runs the same seed, so the same traffic: the per-episode difference
removes most of what the traffic itself does to a driver's speed, and its mean comes with a
confidence interval. Twenty episodes of one scenario differ by a lane change into a lane that
turns out slow: whether "at least as fast" holds is a question of that interval, not only of
the sign of the difference of two means.

    python3 clients/sumo/paired.py RESULTS.json [--baseline OTHER.json]

prints, for every scenario of RESULTS (a `hmdp_sumo.py --json` file), the planner's mean speed
against every other driver of it, and of OTHER's run of the same scenario and seeds (a planner
variant measured without re-running the baselines).
"""

import argparse
import functools
import json
import math
import sys

# Student's t distribution, by its density: enough for the interval of a mean of 2..1000
# differences without scipy (the bridge needs traci and sumolib only).
_SIMPSON_INTERVALS = 4000


def _t_density(t, df):
    log_norm = math.lgamma((df + 1) / 2) - math.lgamma(df / 2) - 0.5 * math.log(df * math.pi)
    return math.exp(log_norm - (df + 1) / 2 * math.log1p(t * t / df))


def t_cdf(t, df):
    """P(T <= t) for Student's t with df degrees of freedom (Simpson's rule from 0)."""
    if t < 0:
        return 1.0 - t_cdf(-t, df)
    n = _SIMPSON_INTERVALS
    h = t / n
    s = _t_density(0.0, df) + _t_density(t, df)
    s += sum((4 if i % 2 else 2) * _t_density(i * h, df) for i in range(1, n))
    return 0.5 + s * h / 3


@functools.lru_cache(maxsize=None)
def t_quantile(p, df):
    """The t with P(T <= t) = p, 0.5 <= p < 1 (bisection on `t_cdf`)."""
    if not 0.5 <= p < 1.0:
        raise ValueError("p must be in [0.5, 1)")
    low, high = 0.0, 1.0
    while t_cdf(high, df) < p:
        high *= 2.0
    for _ in range(60):
        mid = 0.5 * (low + high)
        if t_cdf(mid, df) < p:
            low = mid
        else:
            high = mid
    return 0.5 * (low + high)


def paired_difference(a, b, confidence=0.95):
    """Mean of a[i] - b[i] with its two-sided t interval, and how often a was ahead.

    `a` and `b` are per-episode values of the same seeds, in seed order. The interval is
    None for fewer than two pairs.
    """
    if len(a) != len(b):
        raise ValueError(f"{len(a)} against {len(b)} episodes: not paired")
    if not a:
        raise ValueError("no episodes")
    d = [x - y for x, y in zip(a, b)]
    n = len(d)
    mean = sum(d) / n
    interval = None
    if n >= 2:
        sd = math.sqrt(sum((x - mean) ** 2 for x in d) / (n - 1))
        half = t_quantile(0.5 + confidence / 2, n - 1) * sd / math.sqrt(n)
        interval = (mean - half, mean + half)
    return {
        "pairs": n,
        "mean": mean,
        "interval": interval,
        "confidence": confidence,
        "ahead": sum(1 for x in d if x > 0),
        "behind": sum(1 for x in d if x < 0),
    }


def describe(subject, driver, p, after_s=None):
    """One line of the markdown report and of the command; `after_s`: of the speed from that
    long after the ego's entry on."""
    what = "Mean speed" if after_s is None else f"Mean speed from {after_s:g} s after entry on"
    line = f"{what}, {subject} minus {driver}, paired by seed: {p['mean']:+.2f} m/s"
    if p["interval"] is not None:
        low, high = p["interval"]
        line += f" ({100 * p['confidence']:.0f} % interval {low:+.2f} to {high:+.2f})"
    return line + f"; ahead in {p['ahead']} of {p['pairs']} episodes, behind in {p['behind']}."


def paired_speeds(episodes_by_driver, subject, key="mean_speed_mps"):
    """Per-episode mean speed of `subject` minus each other driver's, paired by seed.

    Unweighted by the episodes' lengths, unlike a summary's mean speed: a pair is one seed.
    `key` is the episode metric: `mean_speed_after_split_mps` for the speed after the entry's
    first seconds; None when some episode has no such value (it ended before, or the run is
    from before the split was recorded).
    """
    if any(e.get(key) is None for episodes in episodes_by_driver.values() for e in episodes):
        return None
    a = [e[key] for e in episodes_by_driver[subject]]
    return {
        driver: paired_difference(a, [e[key] for e in episodes])
        for driver, episodes in episodes_by_driver.items()
        if driver != subject
    }


# The planner's label in the results (hmdp_sumo.py's LABELS).
PLANNER = "planner (HMDP-MPC)"


def _key(scenario):
    s = scenario["scenario"]
    return (s["name"], s["seed"], scenario["episodes"])


def main(argv=None):
    parser = argparse.ArgumentParser(description="The planner against the baselines, paired by seed.")
    parser.add_argument("results")
    parser.add_argument("--baseline", help="another run's JSON with the baselines of the same scenarios and seeds")
    args = parser.parse_args(argv)
    with open(args.results) as f:
        results = json.load(f)
    others = {}
    if args.baseline:
        with open(args.baseline) as f:
            others = {_key(s): s for s in json.load(f)["scenarios"]}
    for scenario in results["scenarios"]:
        episodes = dict(scenario["episode_metrics"])
        if PLANNER not in episodes:
            print(f"{scenario['scenario']['name']}: no planner episodes", file=sys.stderr)
            return 1
        for driver, eps in others.get(_key(scenario), {}).get("episode_metrics", {}).items():
            episodes.setdefault(driver, eps)
        where = f"{scenario['scenario']['name']}, seeds {scenario['scenario']['seed']}..: "
        splits = {e["speed_split_s"] for eps in episodes.values() for e in eps if "speed_split_s" in e}
        if len(splits) > 1:
            print(f"{where}the runs' speeds are split at different times: {sorted(splits)}", file=sys.stderr)
            return 1
        for key, after_s in (("mean_speed_mps", None), ("mean_speed_after_split_mps", next(iter(splits), None))):
            for driver, p in (paired_speeds(episodes, PLANNER, key) or {}).items():
                print(where + describe(PLANNER, driver, p, after_s=after_s))
    return 0


if __name__ == "__main__":
    sys.exit(main())
