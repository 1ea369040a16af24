"""Unit tests of the SUMO <-> protocol mapping and of the SSM parser, on hand-made cases.

    python3 -m unittest discover -s clients/sumo -p 'test_*.py'
"""

import os
import tempfile
import unittest

import traci.constants as tc

import judge
import mapping


def vehicle(front, sumo_lane, lat=0.0, v=30.0, a=0.0, vy=0.0, length=5.0, width=1.8):
    return {
        tc.VAR_LANEPOSITION: front,
        tc.VAR_LANE_INDEX: sumo_lane,
        tc.VAR_LANEPOSITION_LAT: lat,
        tc.VAR_SPEED: v,
        tc.VAR_ACCELERATION: a,
        tc.VAR_SPEED_LAT: vy,
        tc.VAR_LENGTH: length,
        tc.VAR_WIDTH: width,
    }


def protocol_centre_y(lane, lanes, width):
    """docs/protocol.md: lane i (1 = leftmost) has its centre at y = (lanes - i) * width."""
    return (lanes - lane) * width


class LaneMapping(unittest.TestCase):
    def test_rightmost_sumo_lane_is_the_highest_protocol_lane(self):
        self.assertEqual(mapping.protocol_lane(0, 3), 3)
        self.assertEqual(mapping.protocol_lane(2, 3), 1)
        self.assertEqual(mapping.protocol_lane(0, 2), 2)
        self.assertEqual(mapping.protocol_lane(1, 2), 1)
        self.assertEqual(mapping.protocol_lane(3, 4), 1)
        self.assertEqual(mapping.sumo_lane_index(1, 4), 3)
        self.assertEqual(mapping.sumo_lane_index(4, 4), 0)

    def test_round_trip_for_every_lane(self):
        for lanes in (2, 3, 4):
            for k in range(lanes):
                self.assertEqual(mapping.sumo_lane_index(mapping.protocol_lane(k, lanes), lanes), k)

    def test_lanes_off_the_road_are_refused(self):
        for bad in (-1, 3):
            with self.assertRaises(ValueError):
                mapping.protocol_lane(bad, 3)
        for bad in (0, 4):
            with self.assertRaises(ValueError):
                mapping.sumo_lane_index(bad, 3)

    def test_lane_centres_agree_with_the_protocol(self):
        for lanes in (2, 3, 4):
            for k in range(lanes):
                y = mapping.centre_y(k, 0.0, 3.5)
                self.assertAlmostEqual(y, protocol_centre_y(mapping.protocol_lane(k, lanes), lanes, 3.5))

    def test_lateral_offset_moves_left_positive(self):
        # Half way from SUMO lane 1 to lane 2 (to the left) on 3 lanes: on the boundary between
        # protocol lanes 2 (y 3.5) and 1 (y 7.0).
        self.assertAlmostEqual(mapping.centre_y(1, 1.75, 3.5), 5.25)
        # Past the middle SUMO already counts the vehicle on lane 2, with a negative offset.
        self.assertAlmostEqual(mapping.centre_y(2, -1.0, 3.5), 6.0)


class Positions(unittest.TestCase):
    def test_centre_is_half_a_length_behind_the_front(self):
        self.assertAlmostEqual(mapping.centre_x(100.0, 5.0), 97.5)
        self.assertAlmostEqual(mapping.centre_x(12.0, 12.0), 6.0)

    def test_sv_observation(self):
        sv = mapping.sv_observation(7, vehicle(250.0, 0, lat=-0.2, v=22.0, a=-0.5, vy=-0.3, length=12.0, width=2.5), 3.5)
        self.assertEqual(
            sv,
            {
                "id": 7,
                "x_m": 244.0,
                "y_m": -0.2,
                "v_mps": 22.0,
                "a_mps2": -0.5,
                "vy_mps": -0.3,
                "length_m": 12.0,
                "width_m": 2.5,
            },
        )


class Requests(unittest.TestCase):
    def request(self, context, sv_ids=None, memory=None):
        return mapping.plan_request(
            vehicle_id=1,
            sequence=5,
            time_s=160.4,
            road_=mapping.road(3, 3.5, 33.33),
            ego_id="ego",
            context=context,
            desired_speed_mps=33.33,
            maneuver={"lane": 1, "beta": -1},
            memory=memory or mapping.empty_memory(),
            sv_ids=sv_ids or mapping.SvIds(),
        )

    def test_ego_and_svs(self):
        context = {
            "ego": vehicle(505.0, 2, v=28.0),  # leftmost lane: protocol lane 1, y = 7
            "truck.3": vehicle(560.0, 0, v=24.0, length=12.0),  # rightmost: lane 3, y = 0
            "car.1": vehicle(480.0, 1, lat=0.5, v=31.0),
        }
        r = self.request(context)
        self.assertEqual(r["version"], 3)
        self.assertEqual(r["timestamp_ns"], 160_400_000_000)
        self.assertEqual(r["ego"], {"x_m": 502.5, "y_m": 7.0, "v_mps": 28.0, "desired_speed_mps": 33.33, "maneuver": {"lane": 1, "beta": -1}})
        # Ids in order of first sight, the list sorted by id; the ego is not an SV.
        by_id = {s["id"]: s for s in r["svs"]}
        self.assertEqual(sorted(by_id), [1, 2])
        self.assertEqual((by_id[1]["x_m"], by_id[1]["y_m"]), (554.0, 0.0))
        self.assertEqual((by_id[2]["x_m"], by_id[2]["y_m"]), (477.5, 4.0))

    def test_ids_are_stable_across_requests(self):
        ids = mapping.SvIds()
        first = self.request({"ego": vehicle(100.0, 1), "a": vehicle(150.0, 1), "b": vehicle(60.0, 0)}, ids)
        second = self.request({"ego": vehicle(110.0, 1), "c": vehicle(130.0, 2), "b": vehicle(70.0, 0)}, ids)
        self.assertEqual({s["id"]: s["x_m"] for s in first["svs"]}, {1: 147.5, 2: 57.5})
        self.assertEqual({s["id"]: s["x_m"] for s in second["svs"]}, {2: 67.5, 3: 127.5})
        self.assertEqual(ids.sumo_id_of(3), "c")

    def test_perception_range_and_capacity(self):
        context = {"ego": vehicle(1000.0, 1)}
        context["far_behind"] = vehicle(880.0, 1)  # centre 122.5 m behind the ego's: out
        context["far_ahead"] = vehicle(1200.0, 1)  # 200 m ahead: in range, but the farthest
        for i in range(70):
            context[f"n{i:02d}"] = vehicle(1000.0 + 2.0 * (i + 1), i % 3)
        r = self.request(context)
        self.assertEqual(len(r["svs"]), mapping.MAX_SVS)
        xs = sorted(s["x_m"] - 997.5 for s in r["svs"])
        self.assertEqual(xs[0], 2.0)
        self.assertEqual(xs[-1], 128.0)  # the 64 nearest: the far ones are dropped first
        ids = [s["id"] for s in r["svs"]]
        self.assertEqual(ids, sorted(ids))

    def test_memory_goes_back_unchanged(self):
        memory = {"corrective": [{"sv_id": 4, "release_m": 40.0, "trigger_m": 30.0}], "previous_plan": [{"lateral": -1, "longitudinal": 0}]}
        r = self.request({"ego": vehicle(100.0, 1)}, memory=memory)
        self.assertIs(r["memory"], memory)

    def test_initial_maneuver_keeps_the_lane(self):
        self.assertEqual(mapping.initial_maneuver(0, 3), {"lane": 3, "beta": 0})


SSM_XML = """<?xml version="1.0" encoding="UTF-8"?>
<SSMLog>
    <conflict begin="10.00" end="12.00" ego="ego" foe="a">
        <timeSpan values="10.00 10.10 10.20 10.30"/>
        <TTCSpan values="4.00 2.50 NA 1.20"/>
        <DRACSpan values="NA 1.50 3.10 2.00"/>
        <minTTC time="10.30" position="0,0" type="2" value="1.20" speed="20"/>
        <maxDRAC time="10.20" position="0,0" type="2" value="3.10" speed="20"/>
        <PET time="NA" position="NA" type="NA" value="NA" speed="NA"/>
    </conflict>
    <conflict begin="5.00" end="5.20" ego="ego" foe="b">
        <timeSpan values="5.00 5.10 5.20"/>
        <TTCSpan values="0.50 0.40 0.30"/>
        <DRACSpan values="9.00 9.00 9.00"/>
        <PET time="5.10" position="0,0" type="2" value="0.80" speed="20"/>
    </conflict>
    <conflict begin="11.00" end="11.10" ego="ego" foe="c">
        <timeSpan values="11.00 11.10"/>
        <TTCSpan values="2.00 NA"/>
        <DRACSpan values="NA NA"/>
        <PET time="11.10" position="0,0" type="2" value="1.50" speed="20"/>
    </conflict>
    <globalMeasures ego="ego">
        <timeSpan values="5.00 10.00 10.10"/>
        <TGAPSpan values="0.20 1.40 0.90"/>
        <minTGAP time="5.00" position="0,0" value="0.20" leader="b"/>
    </globalMeasures>
</SSMLog>
"""


class SsmParsing(unittest.TestCase):
    def parse(self, from_s):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "ssm.xml")
            with open(path, "w") as f:
                f.write(SSM_XML)
            return judge.parse_ssm(path, from_s=from_s)

    def test_everything(self):
        s = self.parse(0.0)
        self.assertEqual(s["conflicts"], 3)
        self.assertAlmostEqual(s["min_ttc_s"], 0.3)
        self.assertAlmostEqual(s["max_drac_mps2"], 9.0)
        self.assertAlmostEqual(s["min_pet_s"], 0.8)
        self.assertAlmostEqual(s["min_time_headway_s"], 0.2)
        self.assertEqual(s["ttc_critical_times"], {5.0, 5.1, 5.2, 10.1, 10.3, 11.0})

    def test_the_settling_time_is_left_out(self):
        s = self.parse(9.0)
        self.assertEqual(s["conflicts"], 2)
        self.assertAlmostEqual(s["min_ttc_s"], 1.2)
        self.assertAlmostEqual(s["max_drac_mps2"], 3.1)
        self.assertAlmostEqual(s["min_pet_s"], 1.5)
        self.assertAlmostEqual(s["min_time_headway_s"], 0.9)
        self.assertEqual(s["ttc_critical_times"], {10.1, 10.3, 11.0})


if __name__ == "__main__":
    unittest.main()
