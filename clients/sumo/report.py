"""Aggregates episodes per scenario and driver; the JSON document and the markdown tables."""

import math

from judge import SSM_DRAC_LOGGED_ABOVE_MPS2, SSM_TTC_LOGGED_BELOW_S
from paired import describe, paired_speeds

LAYERS = ("nominal", "global_relaxation", "fallback", "watchdog_fallback")


def percentile(values, q):
    """Nearest-rank percentile (q in 0..100) of a non-empty list."""
    ordered = sorted(values)
    rank = max(1, math.ceil(q / 100.0 * len(ordered)))
    return ordered[rank - 1]


def _min(values):
    values = [v for v in values if v is not None]
    return min(values) if values else None


def _max(values):
    values = [v for v in values if v is not None]
    return max(values) if values else None


def summarise(episodes):
    """The summary of one scenario x driver from its episodes' metrics."""
    steps = sum(e["steps"] for e in episodes)
    ssm_steps = sum(e["ssm_steps"] for e in episodes)
    simulated = sum(e["simulated_s"] for e in episodes)
    layers = {}
    for e in episodes:
        for layer, n in e["layers"].items():
            layers[layer] = layers.get(layer, 0) + n
    rtts = [r for e in episodes for r in e["round_trips_s"]]
    lateral = [e["lateral"] for e in episodes if e["lateral"] is not None]
    return {
        "episodes": len(episodes),
        "collisions": sum(e["collisions"] for e in episodes),
        "collisions_sumo_output": sum(e["collisions_sumo_output"]["ego"] for e in episodes),
        "episodes_with_collision": sum(1 for e in episodes if e["collisions"] > 0),
        "sv_collisions": sum(e["sv_collisions"] for e in episodes),
        "simulated_s": simulated,
        # Weighted by time: an episode cut short by a collision weighs less.
        "mean_speed_mps": sum(e["mean_speed_mps"] * e["steps"] for e in episodes) / steps if steps else None,
        "lane_changes_per_min": sum(e["lane_changes"] for e in episodes) / (simulated / 60.0) if simulated else None,
        "min_ttc_s": _min(e["ssm"]["min_ttc_s"] for e in episodes),
        "ttc_below_3s_share": (
            sum(e["ttc_below_3s_share"] * e["ssm_steps"] for e in episodes) / ssm_steps if ssm_steps else None
        ),
        "max_drac_mps2": _max(e["ssm"]["max_drac_mps2"] for e in episodes),
        "min_pet_s": _min(e["ssm"]["min_pet_s"] for e in episodes),
        "min_time_headway_s": _min(e["ssm"]["min_time_headway_s"] for e in episodes),
        "density_at_entry_veh_per_km_lane": sum(e["density_at_entry_veh_per_km_lane"] for e in episodes) / len(episodes),
        "decisions": sum(e["decisions"] for e in episodes),
        "layers": layers,
        "round_trip_p50_ms": percentile(rtts, 50) * 1e3 if rtts else None,
        "round_trip_p99_ms": percentile(rtts, 99) * 1e3 if rtts else None,
        "lane_changes_decided": sum(x["decided"] for x in lateral) if lateral else None,
        "lane_changes_applied": sum(x["applied"] for x in lateral) if lateral else None,
        "lane_changes_not_applied": sum(len(x["not_applied"]) for x in lateral) if lateral else None,
        "max_speed_error_mps": _max(e["max_speed_error_mps"] for e in episodes),
    }


def paired_speed_entry(episodes_by_driver, subject):
    """The JSON's `paired_speed`: over the whole episodes, and after the entry's first seconds."""
    entry = {"subject": subject, "against": paired_speeds(episodes_by_driver, subject)}
    after = paired_speeds(episodes_by_driver, subject, "mean_speed_after_split_mps")
    if after is not None:
        entry["split_s"] = next(iter(episodes_by_driver.values()))[0]["speed_split_s"]
        entry["against_after_split"] = after
    return entry


def _fmt(x, digits=2, none="–"):
    return none if x is None else f"{x:.{digits}f}"


def _ttc(x):
    # SUMO logs an encounter only when a measure passes its threshold: above the TTC
    # threshold the logged values are a partial sample, the honest figure is "above it".
    return f"> {SSM_TTC_LOGGED_BELOW_S:g}" if x is None or x >= SSM_TTC_LOGGED_BELOW_S else f"{x:.2f}"


def _drac(x):
    return f"< {SSM_DRAC_LOGGED_ABOVE_MPS2:g}" if x is None or x < SSM_DRAC_LOGGED_ABOVE_MPS2 else f"{x:.2f}"


def _layers(summary):
    if not summary["decisions"]:
        return "–"
    return " / ".join(str(summary["layers"].get(layer, 0)) for layer in LAYERS)


def markdown(results):
    """One table per scenario, one row per driver."""
    out = []
    for scenario in results["scenarios"]:
        s = scenario["scenario"]
        out.append(
            f"### {s['name']}: {s['lanes']} lanes, {s['flow_veh_per_hour_per_lane']:.0f} veh/h/lane, "
            f"{s['duration_s']:.0f} s, seeds {s['seed']}..{s['seed'] + scenario['episodes'] - 1}\n"
        )
        densities = [d["density_at_entry_veh_per_km_lane"] for d in scenario["drivers"].values()]
        out.append(f"Density when the ego enters: {sum(densities) / len(densities):.1f} veh/km/lane (mean over episodes).\n")
        out.append(
            "| driver | episodes | collisions | mean speed (m/s) | lane changes/min | min TTC (s) | TTC < 3 s | "
            "max DRAC (m/s²) | min PET (s) | min headway (s) | decisions nominal / A / B / watchdog | "
            "round trip p50 / p99 (ms) |"
        )
        out.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for driver, summary in scenario["drivers"].items():
            rt = "–"
            if summary["round_trip_p50_ms"] is not None:
                rt = f"{summary['round_trip_p50_ms']:.1f} / {summary['round_trip_p99_ms']:.1f}"
            out.append(
                f"| {driver} | {summary['episodes']} | {summary['collisions']} | {_fmt(summary['mean_speed_mps'])} | "
                f"{_fmt(summary['lane_changes_per_min'])} | {_ttc(summary['min_ttc_s'])} | "
                f"{_fmt(100 * summary['ttc_below_3s_share'], 2)} % | "
                f"{_drac(summary['max_drac_mps2'])} | "
                f"{_fmt(summary['min_pet_s'])} | {_fmt(summary['min_time_headway_s'])} | {_layers(summary)} | {rt} |"
            )
        out.append("")
        paired = scenario.get("paired_speed")
        if paired:
            for driver, p in paired["against"].items():
                out.append(describe(paired["subject"], driver, p) + "\n")
            for driver, p in paired.get("against_after_split", {}).items():
                out.append(describe(paired["subject"], driver, p, after_s=paired["split_s"]) + "\n")
    return "\n".join(out)
