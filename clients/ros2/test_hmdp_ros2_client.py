"""Tests of hmdp_ros2_client.py: the JSON <-> message conversion, the CDR bytes against a
hand-built encoding, and every subcommand against mock_planner.py over real DDS (discovery
on localhost only). The mock's domain is ROS_DOMAIN_ID and the one no planner is on
HMDP_TEST_EMPTY_DOMAIN, as the system tests reserve them; run alone, a random domain in
100..200 and its neighbour.

    VENV/bin/python -m unittest discover -s clients/ros2
"""

from __future__ import annotations

import copy
import json
import math
import os
import random
import re
import struct
import subprocess
import sys
import tempfile
import unittest
import warnings
from pathlib import Path
from typing import Any

from rclpy.serialization import serialize_message

with warnings.catch_warnings():
    # rclpy's serialization loads rosidl_parser.parser lazily, whose lark warns on import.
    warnings.simplefilter("ignore", DeprecationWarning)
    import rosidl_parser.parser  # noqa: F401

from hmdp_msgs.msg import CorrectiveEntry, Decided, Maneuver, PlanResponse, Rejected
from hmdp_msgs.srv import Plan

import hmdp_ros2_client as client
import hmdp_ros2_convert as convert
import mock_planner

HERE = Path(__file__).resolve().parent
CLIENT = HERE / "hmdp_ros2_client.py"
MOCK = HERE / "mock_planner.py"
PROTOCOL_MD = HERE.parent.parent / "docs" / "protocol.md"


def doc_block(name: str) -> Any:
    """The JSON example ``name`` of docs/protocol.md (between its begin/end markers)."""
    text = PROTOCOL_MD.read_text()
    match = re.search(
        rf"<!-- {name}:begin -->\s*```json\n(.*?)```\s*<!-- {name}:end -->", text, re.DOTALL
    )
    assert match, f"no {name} block in {PROTOCOL_MD}"
    return json.loads(match.group(1))


class Cdr:
    """A hand-written CDR encoder (little endian, alignment after the 4-byte header, zero
    padding): the expectation the rclpy bytes are checked against."""

    def __init__(self) -> None:
        self.buf = bytearray()

    def _put(self, fmt: str, value: Any) -> None:
        size = struct.calcsize(fmt)
        self.buf += bytes(-len(self.buf) % size)
        self.buf += struct.pack("<" + fmt, value)

    def u8(self, v: int) -> None:
        self._put("B", v)

    def i8(self, v: int) -> None:
        self._put("b", v)

    def u16(self, v: int) -> None:
        self._put("H", v)

    def u32(self, v: int) -> None:
        self._put("I", v)

    def u64(self, v: int) -> None:
        self._put("Q", v)

    def f64(self, v: float) -> None:
        self._put("d", v)

    def string(self, s: str) -> None:
        self.u32(len(s) + 1)
        self.buf += s.encode("ascii") + b"\0"

    def raw(self, b: bytes) -> None:
        self.buf += b

    def hex(self) -> str:
        return (b"\x00\x01\x00\x00" + bytes(self.buf)).hex()


def cdr_action(c: Cdr, a: dict[str, int]) -> None:
    c.i8(a["lateral"])
    c.i8(a["longitudinal"])


def cdr_maneuver(c: Cdr, m: dict[str, int]) -> None:
    c.u8(m["lane"])
    c.i8(m["beta"])


def cdr_memory(c: Cdr, m: dict[str, Any]) -> None:
    c.u32(len(m["corrective"]))
    for e in m["corrective"]:
        c.u32(e["sv_id"])
        c.f64(e["release_m"])
        c.f64(e["trigger_m"])
    c.u32(len(m["previous_plan"]))
    for a in m["previous_plan"]:
        cdr_action(c, a)


def cdr_request(doc: dict[str, Any]) -> str:
    """PlanRequest.msg, field by field."""
    c = Cdr()
    c.u16(doc["version"])
    c.u64(doc["vehicle_id"])
    c.u64(doc["sequence"])
    c.u64(doc["timestamp_ns"])
    c.u32(doc["deadline_us"])
    c.u64(doc["sent_at_ns"])
    c.u8(doc["road"]["lanes"])
    c.f64(doc["road"]["lane_width_m"])
    c.f64(doc["road"]["speed_limit_mps"])
    for key in ("x_m", "y_m", "v_mps", "desired_speed_mps"):
        c.f64(doc["ego"][key])
    cdr_maneuver(c, doc["ego"]["maneuver"])
    c.u32(len(doc["svs"]))
    for sv in doc["svs"]:
        c.u32(sv["id"])
        for key in ("x_m", "y_m", "v_mps", "a_mps2", "vy_mps", "length_m", "width_m"):
            c.f64(sv[key])
    cdr_memory(c, doc["memory"])
    return c.hex()


def cdr_response(doc: dict[str, Any]) -> str:
    """PlanResponse.msg, field by field (the unused outcome all defaults)."""
    c = Cdr()
    c.u16(doc["version"])
    c.u64(doc["vehicle_id"])
    c.u64(doc["sequence"])
    c.u32(doc["solve_us"])
    c.u32(doc["queue_us"])
    ((kind, body),) = doc["outcome"].items()
    c.u8(0 if kind == "decided" else 1)
    empty_memory = {"corrective": [], "previous_plan": []}
    d = (
        body
        if kind == "decided"
        else {
            "action": {"lateral": 0, "longitudinal": 0},
            "next_maneuver": {"lane": 0, "beta": 0},
            "setpoint": {"accel_mps2": 0.0, "target_speed_mps": 0.0},
            "plan": [],
            "layer": "nominal",
            "memory": empty_memory,
        }
    )
    cdr_action(c, d["action"])
    cdr_maneuver(c, d["next_maneuver"])
    c.f64(d["setpoint"]["accel_mps2"])
    c.f64(d["setpoint"]["target_speed_mps"])
    c.u32(len(d["plan"]))
    for step in d["plan"]:
        cdr_action(c, step["action"])
        cdr_maneuver(c, step["maneuver"])
        c.f64(step["x_m"])
        c.f64(step["v_mps"])
        c.u16(step["occupied_lanes"])
    c.u8(convert.LAYER_CODES[d["layer"]])
    cdr_memory(c, d["memory"])
    r = body if kind == "rejected" else {"reason": None, "field": ""}
    c.u8(convert.REASON_CODES[r["reason"]] if r["reason"] else 0)
    c.string(r["field"])
    c.raw(bytes.fromhex(doc["signature"]) if doc["signature"] else bytes(64))
    return c.hex()


class ConversionTest(unittest.TestCase):
    """JSON form <-> hmdp_msgs, no DDS."""

    def test_worked_request_is_the_documented_one(self) -> None:
        self.assertEqual(convert.WORKED_REQUEST, doc_block("json-request"))

    def test_round_trips(self) -> None:
        request = doc_block("json-request")
        self.assertEqual(convert.request_to_json(convert.request_from_json(request)), request)
        for name in ("json-response", "json-rejection"):
            response = doc_block(name)
            back = convert.response_to_json(convert.response_from_json(response))
            self.assertEqual(back, response, name)

    def test_message_fields(self) -> None:
        msg = convert.response_from_json(doc_block("json-response"))
        self.assertEqual(msg.outcome, PlanResponse.OUTCOME_DECIDED)
        self.assertEqual(msg.decided.layer, Decided.LAYER_NOMINAL)
        self.assertEqual(len(msg.decided.plan), 2)
        self.assertEqual(bytes(msg.signature[:2]), bytes.fromhex("be69"))
        self.assertEqual(msg.rejected.field, "")  # the other outcome stays default
        msg = convert.response_from_json(doc_block("json-rejection"))
        self.assertEqual(msg.outcome, PlanResponse.OUTCOME_REJECTED)
        self.assertEqual(msg.rejected.reason, Rejected.REASON_NEGATIVE_SPEED)
        self.assertEqual(msg.rejected.field, "ego.v_mps")
        self.assertFalse(any(msg.signature))
        self.assertEqual(len(msg.decided.plan), 0)

    def test_optional_fields_default(self) -> None:
        request = copy.deepcopy(convert.WORKED_REQUEST)
        for key in ("deadline_us", "sent_at_ns", "memory"):
            del request[key]
        for key in ("vy_mps", "length_m", "width_m"):
            del request["svs"][0][key]
        request["road"]["speed_limit_mps"] = 30  # an integer where f64 is expected
        msg = convert.request_from_json(request)
        self.assertEqual((msg.deadline_us, msg.sent_at_ns), (0, 0))
        self.assertEqual((list(msg.memory.corrective), list(msg.memory.previous_plan)), ([], []))
        self.assertEqual(msg.svs[0].vy_mps, 0.0)
        self.assertIsInstance(msg.road.speed_limit_mps, float)
        response = doc_block("json-rejection")
        del response["signature"]
        self.assertEqual(
            convert.response_to_json(convert.response_from_json(response))["signature"], ""
        )

    def test_invalid_documents(self) -> None:
        def request(change: Any) -> dict[str, Any]:
            doc = copy.deepcopy(convert.WORKED_REQUEST)
            change(doc)
            return doc

        bad_requests = {
            "unknown field": request(lambda d: d.update(extra=1)),
            "missing field": request(lambda d: d.pop("road")),
            "u8 overflow": request(lambda d: d["road"].update(lanes=256)),
            "negative u64": request(lambda d: d.update(vehicle_id=-1)),
            "bool as integer": request(lambda d: d.update(sequence=True)),
            "string as number": request(lambda d: d["ego"].update(v_mps="fast")),
            "too many svs": request(lambda d: d.update(svs=d["svs"] * 65)),
            "unknown sv field": request(lambda d: d["svs"][0].update(z_m=0.0)),
            "long memory": request(
                lambda d: d["memory"].update(previous_plan=[{"lateral": 0, "longitudinal": 0}] * 7)
            ),
        }
        for name, doc in bad_requests.items():
            with self.assertRaises(convert.ConversionError, msg=name):
                convert.request_from_json(doc)
        decided = doc_block("json-response")
        rejected = doc_block("json-rejection")
        bad_responses = {
            "unknown layer": (decided, lambda d: d["outcome"]["decided"].update(layer="magic")),
            "unknown reason": (rejected, lambda d: d["outcome"]["rejected"].update(reason="nope")),
            "two outcomes": (
                rejected,
                lambda d: d["outcome"].update(decided=decided["outcome"]["decided"]),
            ),
            "short signature": (decided, lambda d: d.update(signature="00" * 63)),
            "long field": (rejected, lambda d: d["outcome"]["rejected"].update(field="x" * 32)),
        }
        for name, (base, change) in bad_responses.items():
            doc = copy.deepcopy(base)
            change(doc)
            with self.assertRaises(convert.ConversionError, msg=name):
                convert.response_from_json(doc)

    def test_non_finite_numbers(self) -> None:
        request = copy.deepcopy(convert.WORKED_REQUEST)
        request["ego"]["v_mps"] = "NaN"
        request["svs"][0]["x_m"] = "inf"
        request["svs"][0]["a_mps2"] = "-inf"
        msg = convert.request_from_json(request)
        self.assertTrue(math.isnan(msg.ego.v_mps))
        self.assertEqual((msg.svs[0].x_m, msg.svs[0].a_mps2), (math.inf, -math.inf))
        self.assertEqual(convert.json_safe(convert.request_to_json(msg)), request)

    def test_enumerations_match_the_message_constants(self) -> None:
        for code, name in convert.LAYER_NAMES.items():
            self.assertEqual(getattr(Decided, f"LAYER_{name.upper()}"), code)
        for code, name in convert.REASON_NAMES.items():
            self.assertEqual(getattr(Rejected, f"REASON_{name.upper()}"), code)
        layers = [k for k in dir(Decided) if k.startswith("LAYER_") and k.isupper()]
        reasons = [k for k in dir(Rejected) if k.startswith("REASON_") and k.isupper()]
        self.assertEqual(len(layers), len(convert.LAYER_NAMES))
        self.assertEqual(len(reasons), len(convert.REASON_NAMES))

    def test_differing_fields(self) -> None:
        a = doc_block("json-response")
        b = copy.deepcopy(a)
        b["solve_us"], b["queue_us"], b["signature"] = 1, 2, ""
        self.assertEqual(client.differing_fields(a, b), [])
        b["outcome"]["decided"]["setpoint"]["accel_mps2"] = -0.0  # bit for bit: -0.0 != 0.0
        b["outcome"]["decided"]["layer"] = "fallback"
        self.assertEqual(client.differing_fields(a, b), ["setpoint", "layer"])
        self.assertEqual(
            client.differing_fields(a, doc_block("json-rejection")), ["sequence", "outcome"]
        )


class CdrTest(unittest.TestCase):
    """rclpy's bytes against hand-built expectations (the recipe's reference-bytes trick)."""

    def test_tiny_messages(self) -> None:
        # uint8 reason, 3 padding bytes, string = uint32 length with the NUL, bytes, NUL.
        self.assertEqual(
            convert.cdr_hex(Rejected(reason=12, field="ego.v_mps")),
            "000100000c0000000a000000" + b"ego.v_mps\0".hex(),
        )
        # uint8 + int8; Fast DDS pads a fixed-size type to a multiple of 4.
        self.assertEqual(convert.cdr_hex(Maneuver(lane=2, beta=-1)), "0001000002ff0000")
        # uint32, 4 padding bytes (8-byte alignment of float64), two float64.
        self.assertEqual(
            convert.cdr_hex(CorrectiveEntry(sv_id=1, release_m=1.0, trigger_m=2.5)),
            "000100000100000000000000000000000000f03f0000000000000440",
        )

    def test_worked_messages(self) -> None:
        request = doc_block("json-request")
        self.assertEqual(convert.cdr_hex(convert.request_from_json(request)), cdr_request(request))
        for name in ("json-response", "json-rejection"):
            response = doc_block(name)
            self.assertEqual(
                convert.cdr_hex(convert.response_from_json(response)), cdr_response(response), name
            )

    def test_raw_bytes_differ_only_in_padding(self) -> None:
        msg = convert.request_from_json(convert.WORKED_REQUEST)
        expected = bytes.fromhex(cdr_request(convert.WORKED_REQUEST))
        raw = serialize_message(msg)
        self.assertEqual(len(raw), len(expected))
        zeroed = convert.cdr_padding_zeroed(type(msg), raw)
        self.assertEqual(zeroed, expected)
        for r, z in zip(raw, zeroed, strict=True):
            self.assertTrue(r == z or z == 0)

    def test_service_payloads_are_the_messages(self) -> None:
        msg = convert.request_from_json(convert.WORKED_REQUEST)
        self.assertEqual(convert.cdr_hex(Plan.Request(request=msg)), convert.cdr_hex(msg))
        response = convert.response_from_json(doc_block("json-rejection"))
        self.assertEqual(convert.cdr_hex(Plan.Response(response=response)), convert.cdr_hex(response))

    def test_cdr_subcommand(self) -> None:
        for kind, name, expected in (
            ("PlanRequest", "json-request", cdr_request),
            ("PlanResponse", "json-response", cdr_response),
            ("PlanResponse", "json-rejection", cdr_response),
        ):
            doc = doc_block(name)
            out = subprocess.run(
                [sys.executable, str(CLIENT), "cdr", kind],
                input=json.dumps(doc),
                capture_output=True,
                text=True,
                timeout=60,
            )
            self.assertEqual(out.returncode, 0, out.stderr)
            self.assertEqual(out.stdout.strip(), expected(doc), name)
        out = subprocess.run(
            [sys.executable, str(CLIENT), "cdr", "PlanRequest"],
            input='{"version": 3}',
            capture_output=True,
            text=True,
            timeout=60,
        )
        self.assertEqual(out.returncode, 2)
        self.assertIn("error", json.loads(out.stdout))


def ros_env(domain: int, log_dir: str) -> dict[str, str]:
    """The test's ROS environment: its own domain, discovery on this machine only, and rcl's
    log files (one per process) in a temporary directory rather than ~/.ros/log."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_LOG_DIR"] = log_dir
    return env


def write_recording(
    path: Path, requests: list[dict[str, Any]], responses: list[dict[str, Any]]
) -> None:
    """A planner recording: JSON messages on /planner/request and /planner/response."""
    from mcap.writer import Writer

    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="test_hmdp_ros2_client")
        channels = {}
        for topic, schema in (
            ("/planner/request", "hmdp.PlanRequest"),
            ("/planner/response", "hmdp.PlanResponse"),
        ):
            schema_id = writer.register_schema(name=schema, encoding="jsonschema", data=b"{}")
            channels[topic] = writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_id
            )
        t = 1_000_000_000
        for topic, docs in (("/planner/request", requests), ("/planner/response", responses)):
            for doc in docs:
                t += 1000
                data = json.dumps(convert.json_safe(doc)).encode()
                writer.add_message(
                    channel_id=channels[topic], log_time=t, data=data, publish_time=t
                )
        writer.finish()


class WithMockPlannerTest(unittest.TestCase):
    """Every subcommand against mock_planner.py, as separate processes over DDS."""

    domain: int
    logs: tempfile.TemporaryDirectory
    mock_stderr: Any
    mock: subprocess.Popen

    @classmethod
    def setUpClass(cls) -> None:
        cls.domain = int(os.environ.get("ROS_DOMAIN_ID") or random.randint(100, 200))
        cls.logs = tempfile.TemporaryDirectory()
        cls.mock_stderr = open(Path(cls.logs.name) / "mock_planner.stderr", "w")  # noqa: SIM115
        cls.mock = subprocess.Popen(
            [sys.executable, str(MOCK), "--max-seconds", "300"],
            env=ros_env(cls.domain, cls.logs.name),
            stdout=subprocess.DEVNULL,
            stderr=cls.mock_stderr,
        )

    @classmethod
    def tearDownClass(cls) -> None:
        cls.mock.terminate()
        try:
            cls.mock.wait(timeout=15)
        except subprocess.TimeoutExpired:
            cls.mock.kill()
            cls.mock.wait()
        cls.mock_stderr.close()
        cls.logs.cleanup()

    def run_client(self, *args: str, domain: int | None = None) -> tuple[int, Any]:
        self.assertIsNone(self.mock.poll(), "the mock planner died")
        out = subprocess.run(
            [sys.executable, str(CLIENT), *args],
            env=ros_env(self.domain if domain is None else domain, self.logs.name),
            capture_output=True,
            text=True,
            timeout=120,
        )
        lines = out.stdout.strip().splitlines()
        self.assertEqual(len(lines), 1, f"stdout: {out.stdout!r}\nstderr: {out.stderr}")
        return out.returncode, json.loads(lines[0])

    def test_markers(self) -> None:
        code, report = self.run_client("markers", "--count", "3")
        self.assertEqual(code, 0, report)
        self.assertEqual(report["sent"], 3)
        self.assertEqual(report["answered"], 3)
        self.assertEqual(report["decisions_of_these_requests"], 3)
        self.assertEqual(report["marker_arrays"], 3)
        self.assertEqual(
            report["last_marker_array"],
            {"markers": 3, "namespaces": {"ego": 1, "plan": 1, "svs": 1}},
        )

    def test_reject(self) -> None:
        code, cases = self.run_client("reject")
        self.assertEqual(code, 0, cases)
        got = [(c["case"], c["outcome"], c["reason"], c["reason_name"], c["field"]) for c in cases]
        self.assertEqual(
            got,
            [
                ("beta_5", "rejected", 15, "beta_out_of_range", "ego.maneuver.beta"),
                ("nan_ego_speed", "rejected", 10, "non_finite", "ego.v_mps"),
                ("lane_0", "rejected", 14, "lane_out_of_range", "ego.maneuver.lane"),
                ("duplicate_sv_id", "rejected", 16, "duplicate_sv_id", "sv.id"),
            ],
        )

    def recording(self) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """Five requests and the mock's answers to them, as a planner would record them."""
        requests = []
        for sequence in range(1, 6):
            doc = copy.deepcopy(convert.WORKED_REQUEST)
            doc["sequence"] = sequence
            doc["ego"]["x_m"] = 10.0 * sequence
            requests.append(doc)
        requests[4]["ego"]["v_mps"] = "NaN"  # a faulty request, recorded as a string
        responses = [
            convert.response_to_json(mock_planner.canned_answer(convert.request_from_json(r)))
            for r in requests
        ]
        return requests, responses

    def test_replay_identical(self) -> None:
        requests, responses = self.recording()
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "run.mcap"
            write_recording(path, requests, responses)
            code, report = self.run_client("replay", str(path))
        self.assertEqual(code, 0, report)
        self.assertEqual(
            report,
            {
                "sent": 5,
                "identical": 5,
                "different": 0,
                "differences": [],
                "unanswered": 0,
                "timing_fallbacks_not_compared": 0,
                "without_recorded_answer": 0,
            },
        )

    def test_replay_differences(self) -> None:
        requests, responses = self.recording()
        responses[1]["outcome"]["decided"]["setpoint"]["accel_mps2"] = 0.5
        responses[1]["solve_us"] = 99999  # ignored
        responses[2]["outcome"]["decided"]["layer"] = "watchdog_fallback"
        responses[2]["outcome"]["decided"]["plan"] = []
        responses[3]["outcome"] = {"rejected": {"reason": "overloaded", "field": ""}}
        extra = copy.deepcopy(convert.WORKED_REQUEST)
        extra["sequence"] = 99
        del responses[0]
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "run.mcap"
            write_recording(path, requests + [extra], responses)
            code, report = self.run_client("replay", str(path))
        self.assertEqual(code, 1, report)
        self.assertEqual(report["sent"], 6)
        self.assertEqual(report["identical"], 1)  # the NaN request's rejection
        self.assertEqual(report["different"], 2)
        self.assertEqual(report["timing_fallbacks_not_compared"], 1)
        self.assertEqual(report["without_recorded_answer"], 2)
        self.assertEqual(report["unanswered"], 0)
        self.assertEqual(
            [(d["sequence"], d["fields"]) for d in report["differences"]],
            [(2, ["setpoint"]), (4, ["outcome"])],
        )
        self.assertEqual(
            report["differences"][0]["recorded"]["decided"]["setpoint"]["accel_mps2"], 0.5
        )

    def test_replay_bad_file(self) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "broken.mcap"
            path.write_bytes(b"\x89MCAP0\r\n" + b"garbage")
            code, report = self.run_client("replay", str(path))
        self.assertEqual(code, 2)
        self.assertIn("broken.mcap", report["error"])

    def test_no_planner(self) -> None:
        # A domain other tests running at the same time do not use (the harness reserves one).
        empty = int(os.environ.get("HMDP_TEST_EMPTY_DOMAIN") or self.domain + 1)
        code, report = self.run_client("reject", "--discovery-timeout", "1", domain=empty)
        self.assertEqual(code, 2)
        self.assertIn("not available", report["error"])


if __name__ == "__main__":
    unittest.main()
