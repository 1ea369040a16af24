"""The paired comparison: Student's t against printed tables, an example by hand, and the
interval's coverage on seeded normal samples.

    python3 -m unittest discover -s clients/sumo -p 'test_*.py'
"""

import contextlib
import io
import json
import os
import random
import tempfile
import unittest

import paired
from paired import describe, paired_difference, t_quantile
from report import paired_speed_entry


class StudentT(unittest.TestCase):
    def test_quantiles_match_the_printed_table(self):
        # Two-sided 95 % (p = 0.975) and one-sided 95 % critical values, as tabulated.
        for p, df, table in [(0.975, 1, 12.706), (0.975, 4, 2.776), (0.975, 9, 2.262), (0.975, 19, 2.093), (0.95, 4, 2.132), (0.995, 30, 2.750)]:
            self.assertAlmostEqual(t_quantile(p, df), table, delta=1e-3, msg=f"p {p}, df {df}")

    def test_large_df_approaches_the_normal_quantile(self):
        self.assertAlmostEqual(t_quantile(0.975, 1000), 1.962, delta=1e-3)


class PairedDifference(unittest.TestCase):
    def test_an_example_by_hand(self):
        # d = 1, 0, -1, 2: mean 0.5, s = sqrt(5 / 3), half width t(0.975, 3) s / 2 = 3.182 * 1.291 / 2.
        p = paired_difference([30.0, 31.0, 29.0, 32.0], [29.0, 31.0, 30.0, 30.0])
        self.assertAlmostEqual(p["mean"], 0.5)
        low, high = p["interval"]
        self.assertAlmostEqual(low, 0.5 - 2.0544, delta=1e-3)
        self.assertAlmostEqual(high, 0.5 + 2.0544, delta=1e-3)
        self.assertEqual((p["pairs"], p["ahead"], p["behind"]), (4, 2, 1))

    def test_one_pair_has_no_interval_and_unequal_runs_are_refused(self):
        self.assertIsNone(paired_difference([1.0], [0.5])["interval"])
        with self.assertRaises(ValueError):
            paired_difference([1.0, 2.0], [1.0])

    def test_the_interval_covers_the_true_difference_as_often_as_it_says(self):
        # Five pairs: a normal quantile (1.96 instead of 2.776) would cover about 88 %.
        rng = random.Random(2026)
        trials, covered = 4000, 0
        for _ in range(trials):
            b = [rng.gauss(29.0, 1.0) for _ in range(5)]
            a = [x + 0.3 + rng.gauss(0.0, 0.5) for x in b]
            low, high = paired_difference(a, b)["interval"]
            covered += low <= 0.3 <= high
        self.assertAlmostEqual(covered / trials, 0.95, delta=0.012)


class SplitAtEntry(unittest.TestCase):
    @staticmethod
    def episode(whole, after):
        return {"mean_speed_mps": whole, "mean_speed_after_split_mps": after, "speed_split_s": 20.0}

    def test_the_speed_after_the_split_is_paired_on_its_own(self):
        # Behind over the whole episodes (the entry), ahead after it: both reported, each paired.
        runs = {
            "planner": [self.episode(28.0, 29.5), self.episode(30.0, 31.0)],
            "krauss": [self.episode(28.5, 29.0), self.episode(30.2, 30.5)],
        }
        entry = paired_speed_entry(runs, "planner")
        self.assertAlmostEqual(entry["against"]["krauss"]["mean"], -0.35)
        self.assertAlmostEqual(entry["against_after_split"]["krauss"]["mean"], 0.5)
        self.assertEqual(entry["split_s"], 20.0)
        self.assertEqual(entry["against_after_split"]["krauss"]["behind"], 0)
        line = describe("planner", "krauss", entry["against_after_split"]["krauss"], after_s=entry["split_s"])
        self.assertTrue(line.startswith("Mean speed from 20 s after entry on, planner minus krauss"), line)

    def test_no_split_pairs_when_an_episode_ended_before_the_split(self):
        runs = {
            "planner": [self.episode(28.0, None), self.episode(30.0, 31.0)],
            "krauss": [self.episode(28.5, 29.0), self.episode(30.2, 30.5)],
        }
        entry = paired_speed_entry(runs, "planner")
        self.assertNotIn("against_after_split", entry)
        self.assertAlmostEqual(entry["against"]["krauss"]["mean"], -0.35)


class PairedCommand(unittest.TestCase):
    @staticmethod
    def results(driver, episodes):
        scenario = {"name": "s", "seed": 1000}
        return {"scenarios": [{"scenario": scenario, "episodes": len(episodes), "episode_metrics": {driver: episodes}}]}

    def run_command(self, planner, baseline):
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for name, doc in (("planner.json", planner), ("baseline.json", baseline)):
                paths.append(os.path.join(tmp, name))
                with open(paths[-1], "w") as f:
                    json.dump(doc, f)
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = paired.main([paths[0], "--baseline", paths[1]])
            return code, out.getvalue().splitlines(), err.getvalue()

    def test_both_lines_against_another_runs_baseline(self):
        planner = self.results(paired.PLANNER, [SplitAtEntry.episode(28.0, 29.5), SplitAtEntry.episode(30.0, 31.0)])
        krauss = self.results("krauss", [SplitAtEntry.episode(28.5, 29.0), SplitAtEntry.episode(30.2, 30.5)])
        code, lines, _ = self.run_command(planner, krauss)
        self.assertEqual(code, 0)
        self.assertEqual(len(lines), 2, lines)
        self.assertIn("Mean speed, ", lines[0])
        self.assertIn("-0.35 m/s", lines[0])
        self.assertIn("Mean speed from 20 s after entry on", lines[1])
        self.assertIn("+0.50 m/s", lines[1])

    def test_a_baseline_split_at_another_time_is_refused(self):
        planner = self.results(paired.PLANNER, [SplitAtEntry.episode(28.0, 29.5), SplitAtEntry.episode(30.0, 31.0)])
        other = [dict(SplitAtEntry.episode(28.5, 29.0), speed_split_s=10.0), dict(SplitAtEntry.episode(30.2, 30.5), speed_split_s=10.0)]
        code, _, err = self.run_command(planner, self.results("krauss", other))
        self.assertEqual(code, 1)
        self.assertIn("split at different times", err)


if __name__ == "__main__":
    unittest.main()
