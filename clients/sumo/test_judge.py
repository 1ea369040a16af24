"""The judge against real SUMO: a staged rear-end collision must be seen by TraCI, in SUMO's
collision output and in its SSM output, and a safe following must not.

    python3 -m unittest discover -s clients/sumo -p 'test_*.py'
"""

import contextlib
import io
import os
import tempfile
import unittest

import traci

import control
import judge
import scenario as scenarios
from scenario import EDGE_ID, EGO_ID


def staged_run(directory, ego_speed, leader_speed, seconds=12.0):
    """The ego (speed mode 0, constant speed) behind a leader at constant speed, 60 m apart."""
    s = scenarios.Scenario(name="staged", lanes=2, length_m=1000.0, duration_s=10.0, ego_depart_pos_m=50.0, ego_desired_speed_mps=25.0)
    net = scenarios.write_network(s, directory)
    routes = os.path.join(directory, "staged.rou.xml")
    with open(routes, "w") as f:
        f.write(
            f'<routes>\n  <vType id="car" length="5" width="1.8" sigma="0"/>\n  <route id="r" edges="{EDGE_ID}"/>\n'
            f'  <vehicle id="leader" type="car" route="r" depart="0" departLane="0" departPos="110" departSpeed="{leader_speed}"/>\n'
            f'  <vehicle id="{EGO_ID}" type="car" route="r" depart="0" departLane="0" departPos="50" departSpeed="{ego_speed}"/>\n'
            "</routes>\n"
        )
    command = control.sumo_command(s, net, routes, seed=1, directory=directory)
    with contextlib.redirect_stdout(io.StringIO()):
        traci.start(command)
    watch = judge.CollisionWatch()
    try:
        traci.simulationStep()
        for vehicle, speed in ((EGO_ID, ego_speed), ("leader", leader_speed)):
            traci.vehicle.setSpeedMode(vehicle, 0)
            traci.vehicle.setLaneChangeMode(vehicle, 0)
            traci.vehicle.setSpeed(vehicle, speed)
        while traci.simulation.getTime() < seconds:
            traci.simulationStep()
            watch.observe(traci.simulation.getCollisions(), traci.simulation.getTime())
    finally:
        traci.close()
    return watch


class StagedEncounters(unittest.TestCase):
    def test_a_rear_end_collision_is_counted_once_everywhere(self):
        with tempfile.TemporaryDirectory() as d:
            # 55 m of gap closed at 10 m/s: contact after about 5.5 s, then overlapping.
            watch = staged_run(d, ego_speed=30.0, leader_speed=20.0)
            self.assertEqual(list(watch.ego_pairs), [("ego", "leader")])
            self.assertGreater(watch.ego_pairs[("ego", "leader")]["time_s"], 4.0)
            from_file = judge.parse_collisions(os.path.join(d, "collisions.xml"))
            self.assertEqual((from_file["ego"], from_file["others"]), (1, 0))
            ssm = judge.parse_ssm(os.path.join(d, "ssm.xml"))
            self.assertLess(ssm["min_ttc_s"], 0.5)
            self.assertGreater(ssm["max_drac_mps2"], 5.0)
            self.assertTrue(ssm["ttc_critical_times"])

    def test_a_safe_following_is_not_a_collision(self):
        with tempfile.TemporaryDirectory() as d:
            watch = staged_run(d, ego_speed=20.0, leader_speed=20.0)
            self.assertEqual(watch.ego_pairs, {})
            self.assertEqual(judge.parse_collisions(os.path.join(d, "collisions.xml"))["ego"], 0)
            ssm = judge.parse_ssm(os.path.join(d, "ssm.xml"))
            self.assertIsNone(ssm["min_ttc_s"])  # no approach: SUMO has no TTC to log
            self.assertAlmostEqual(ssm["min_time_headway_s"], 55.0 / 20.0, places=1)


if __name__ == "__main__":
    unittest.main()
