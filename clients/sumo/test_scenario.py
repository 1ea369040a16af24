"""Scenario files: the keys reach the route file SUMO reads.

    python3 -m unittest discover -s clients/sumo -p 'test_*.py'
"""

import os
import tempfile
import unittest
import xml.etree.ElementTree as ET

import scenario as scenarios


def ego_vtype_attributes(scenario, driver):
    with tempfile.TemporaryDirectory() as d:
        path = scenarios.write_routes(scenario, driver, d)
        root = ET.parse(path).getroot()
    ego = next(v for v in root.iter("vehicle") if v.get("id") == scenarios.EGO_ID)
    return next(t for t in root.iter("vType") if t.get("id") == ego.get("type")).attrib


class ScenarioFileTest(unittest.TestCase):
    def load(self, text):
        with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
            f.write(text)
        try:
            return scenarios.load_scenario(f.name)
        finally:
            os.unlink(f.name)

    def test_the_sumo_egos_acceleration_reaches_their_vtype(self):
        s = self.load("lanes = 2\nego_accel_mps2 = 1.5\n")
        for driver in ("krauss", "idm"):
            self.assertEqual(float(ego_vtype_attributes(s, driver)["accel"]), 1.5, driver)
        # Without the key, SUMO's default.
        self.assertEqual(float(ego_vtype_attributes(self.load("lanes = 2\n"), "krauss")["accel"]), 2.6)

    def test_a_non_positive_acceleration_is_refused(self):
        with self.assertRaisesRegex(ValueError, "ego_accel_mps2 must be positive"):
            self.load("ego_accel_mps2 = 0.0\n")

    def test_every_shipped_scenario_loads(self):
        directory = os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenarios")
        names = sorted(f for f in os.listdir(directory) if f.endswith(".toml"))
        self.assertGreaterEqual(len(names), 11)
        for name in names:
            s = scenarios.load_scenario(os.path.join(directory, name))
            self.assertEqual(s.name, name[: -len(".toml")])


if __name__ == "__main__":
    unittest.main()
