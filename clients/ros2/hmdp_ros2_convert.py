"""The planner's messages between the protocol's JSON form and hmdp_msgs, and their CDR bytes.

``request_from_json`` / ``request_to_json`` and ``response_from_json`` / ``response_to_json``
convert between the protocol's JSON form (a dict, docs/protocol.md "JSON form") and the
hmdp_msgs messages, checking what the JSON form requires (known keys only, integer ranges,
capacities, enumeration names). ``cdr_padding_zeroed`` makes rclpy's CDR bytes comparable:
Fast CDR leaves its alignment padding unwritten, so ``cdr_hex`` zeroes it. Used by
hmdp_ros2_client.py; copy it into a ROS 2 stack as it is.
"""

from __future__ import annotations

import importlib
import math
import struct
from collections.abc import Mapping, Sequence
from typing import Any

import rosidl_parser.definition as idl
from hmdp_msgs.msg import (
    Action,
    CorrectiveEntry,
    Decided,
    EgoState,
    Maneuver,
    PlannerMemory,
    PlanRequest,
    PlanResponse,
    PlanStep,
    Rejected,
    Road,
    SetPoint,
    SvObservation,
)
from rclpy.serialization import serialize_message

PROTOCOL_VERSION = 3

# Capacities of the protocol (and the bounds of the .msg files).
MAX_SVS = 64
MAX_CORRECTIVE = 16
MAX_HORIZON = 6
MAX_FIELD_LEN = 31
SIGNATURE_LEN = 64

# Enumerations: code <-> snake_case name (docs/protocol.md, "Enumerations").
LAYER_NAMES: dict[int, str] = {
    0: "nominal",
    1: "global_relaxation",
    2: "fallback",
    3: "watchdog_fallback",
    4: "stale_fallback",
}
REASON_NAMES: dict[int, str] = {
    1: "unsupported_version",
    2: "capacity_exceeded",
    10: "non_finite",
    11: "out_of_range",
    12: "negative_speed",
    13: "lane_count",
    14: "lane_out_of_range",
    15: "beta_out_of_range",
    16: "duplicate_sv_id",
    17: "too_many_vehicles",
    18: "invalid_memory",
    30: "malformed",
    31: "overloaded",
    32: "internal_error",
}
LAYER_CODES = {name: code for code, name in LAYER_NAMES.items()}
REASON_CODES = {name: code for code, name in REASON_NAMES.items()}

# Answers given by the service's timing, not by the solver: not comparable in a replay.
TIMING_LAYERS = ("watchdog_fallback", "stale_fallback")

# Recordings write a non-finite number as one of these strings (docs/recording.md).
NON_FINITE_STRINGS = {"NaN": math.nan, "inf": math.inf, "-inf": -math.inf}

# The worked request of docs/protocol.md ("JSON form").
WORKED_REQUEST: dict[str, Any] = {
    "version": 3,
    "vehicle_id": 7,
    "sequence": 42,
    "timestamp_ns": 1000000000,
    "deadline_us": 0,
    "sent_at_ns": 1767225600000000000,
    "road": {"lanes": 3, "lane_width_m": 3.5, "speed_limit_mps": 30.0},
    "ego": {
        "x_m": 0.0,
        "y_m": 3.5,
        "v_mps": 25.0,
        "desired_speed_mps": 28.0,
        "maneuver": {"lane": 2, "beta": 0},
    },
    "svs": [
        {
            "id": 1,
            "x_m": 30.0,
            "y_m": 3.5,
            "v_mps": 20.0,
            "a_mps2": -0.5,
            "vy_mps": 0.25,
            "length_m": 4.5,
            "width_m": 0.0,
        }
    ],
    "memory": {"corrective": [], "previous_plan": [{"lateral": 0, "longitudinal": 1}]},
}


# ---------------------------------------------------------------------------------------------
# JSON form <-> hmdp_msgs
# ---------------------------------------------------------------------------------------------


class ConversionError(ValueError):
    """A JSON document that is not a valid protocol message (the path names the field)."""


def _fields(
    doc: Any, where: str, required: Sequence[str], optional: Sequence[str] = ()
) -> Mapping[str, Any]:
    """Checks that ``doc`` is an object with every required key and no unknown one."""
    if not isinstance(doc, dict):
        raise ConversionError(f"{where or 'message'}: expected an object")
    unknown = sorted(set(doc) - set(required) - set(optional))
    if unknown:
        raise ConversionError(f"{where or 'message'}: unknown field(s) {', '.join(unknown)}")
    for key in required:
        if key not in doc:
            raise ConversionError(f"{_join(where, key)}: missing")
    return doc


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _uint(value: Any, bits: int, where: str) -> int:
    """An unsigned integer of ``bits`` bits (a JSON integer, never a bool or a float)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConversionError(f"{where}: expected an integer")
    if not 0 <= value < (1 << bits):
        raise ConversionError(f"{where}: {value} does not fit u{bits}")
    return value


def _int(value: Any, bits: int, where: str) -> int:
    """A signed integer of ``bits`` bits."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConversionError(f"{where}: expected an integer")
    if not -(1 << (bits - 1)) <= value < (1 << (bits - 1)):
        raise ConversionError(f"{where}: {value} does not fit i{bits}")
    return value


def _f64(value: Any, where: str) -> float:
    """A float64: a JSON number, or one of the recordings' strings "NaN", "inf", "-inf"."""
    if isinstance(value, str) and value in NON_FINITE_STRINGS:
        return NON_FINITE_STRINGS[value]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConversionError(f"{where}: expected a number")
    return float(value)


def _list(value: Any, capacity: int, where: str) -> list[Any]:
    if not isinstance(value, list):
        raise ConversionError(f"{where}: expected an array")
    if len(value) > capacity:
        raise ConversionError(f"{where}: {len(value)} elements, capacity {capacity}")
    return value


def action_from_json(doc: Any, where: str = "action") -> Action:
    d = _fields(doc, where, ("lateral", "longitudinal"))
    return Action(
        lateral=_int(d["lateral"], 8, _join(where, "lateral")),
        longitudinal=_int(d["longitudinal"], 8, _join(where, "longitudinal")),
    )


def action_to_json(msg: Action) -> dict[str, Any]:
    return {"lateral": int(msg.lateral), "longitudinal": int(msg.longitudinal)}


def maneuver_from_json(doc: Any, where: str = "maneuver") -> Maneuver:
    d = _fields(doc, where, ("lane", "beta"))
    return Maneuver(
        lane=_uint(d["lane"], 8, _join(where, "lane")),
        beta=_int(d["beta"], 8, _join(where, "beta")),
    )


def maneuver_to_json(msg: Maneuver) -> dict[str, Any]:
    return {"lane": int(msg.lane), "beta": int(msg.beta)}


def memory_from_json(doc: Any, where: str = "memory") -> PlannerMemory:
    d = _fields(doc, where, ("corrective", "previous_plan"))
    corrective = []
    for i, entry in enumerate(_list(d["corrective"], MAX_CORRECTIVE, _join(where, "corrective"))):
        at = f"{where}.corrective[{i}]"
        e = _fields(entry, at, ("sv_id", "release_m", "trigger_m"))
        corrective.append(
            CorrectiveEntry(
                sv_id=_uint(e["sv_id"], 32, _join(at, "sv_id")),
                release_m=_f64(e["release_m"], _join(at, "release_m")),
                trigger_m=_f64(e["trigger_m"], _join(at, "trigger_m")),
            )
        )
    previous = [
        action_from_json(a, f"{where}.previous_plan[{i}]")
        for i, a in enumerate(_list(d["previous_plan"], MAX_HORIZON, _join(where, "previous_plan")))
    ]
    return PlannerMemory(corrective=corrective, previous_plan=previous)


def memory_to_json(msg: PlannerMemory) -> dict[str, Any]:
    return {
        "corrective": [
            {
                "sv_id": int(e.sv_id),
                "release_m": float(e.release_m),
                "trigger_m": float(e.trigger_m),
            }
            for e in msg.corrective
        ],
        "previous_plan": [action_to_json(a) for a in msg.previous_plan],
    }


def request_from_json(doc: Any) -> PlanRequest:
    """A ``PlanRequest`` message from the protocol's JSON form (a dict).

    ``deadline_us``, ``sent_at_ns`` and ``memory`` may be omitted (0, 0, empty), as may an
    SV's ``vy_mps``, ``length_m`` and ``width_m`` (0). Raises ``ConversionError``.
    """
    d = _fields(
        doc,
        "",
        ("version", "vehicle_id", "sequence", "timestamp_ns", "road", "ego", "svs"),
        ("deadline_us", "sent_at_ns", "memory"),
    )
    road = _fields(d["road"], "road", ("lanes", "lane_width_m", "speed_limit_mps"))
    ego = _fields(d["ego"], "ego", ("x_m", "y_m", "v_mps", "desired_speed_mps", "maneuver"))
    svs = []
    for i, sv in enumerate(_list(d["svs"], MAX_SVS, "svs")):
        at = f"svs[{i}]"
        s = _fields(
            sv, at, ("id", "x_m", "y_m", "v_mps", "a_mps2"), ("vy_mps", "length_m", "width_m")
        )
        svs.append(
            SvObservation(
                id=_uint(s["id"], 32, _join(at, "id")),
                x_m=_f64(s["x_m"], _join(at, "x_m")),
                y_m=_f64(s["y_m"], _join(at, "y_m")),
                v_mps=_f64(s["v_mps"], _join(at, "v_mps")),
                a_mps2=_f64(s["a_mps2"], _join(at, "a_mps2")),
                vy_mps=_f64(s.get("vy_mps", 0.0), _join(at, "vy_mps")),
                length_m=_f64(s.get("length_m", 0.0), _join(at, "length_m")),
                width_m=_f64(s.get("width_m", 0.0), _join(at, "width_m")),
            )
        )
    memory = d.get("memory", {"corrective": [], "previous_plan": []})
    return PlanRequest(
        version=_uint(d["version"], 16, "version"),
        vehicle_id=_uint(d["vehicle_id"], 64, "vehicle_id"),
        sequence=_uint(d["sequence"], 64, "sequence"),
        timestamp_ns=_uint(d["timestamp_ns"], 64, "timestamp_ns"),
        deadline_us=_uint(d.get("deadline_us", 0), 32, "deadline_us"),
        sent_at_ns=_uint(d.get("sent_at_ns", 0), 64, "sent_at_ns"),
        road=Road(
            lanes=_uint(road["lanes"], 8, "road.lanes"),
            lane_width_m=_f64(road["lane_width_m"], "road.lane_width_m"),
            speed_limit_mps=_f64(road["speed_limit_mps"], "road.speed_limit_mps"),
        ),
        ego=EgoState(
            x_m=_f64(ego["x_m"], "ego.x_m"),
            y_m=_f64(ego["y_m"], "ego.y_m"),
            v_mps=_f64(ego["v_mps"], "ego.v_mps"),
            desired_speed_mps=_f64(ego["desired_speed_mps"], "ego.desired_speed_mps"),
            maneuver=maneuver_from_json(ego["maneuver"], "ego.maneuver"),
        ),
        svs=svs,
        memory=memory_from_json(memory, "memory"),
    )


def request_to_json(msg: PlanRequest) -> dict[str, Any]:
    """The protocol's JSON form of a ``PlanRequest`` message (every field present)."""
    return {
        "version": int(msg.version),
        "vehicle_id": int(msg.vehicle_id),
        "sequence": int(msg.sequence),
        "timestamp_ns": int(msg.timestamp_ns),
        "deadline_us": int(msg.deadline_us),
        "sent_at_ns": int(msg.sent_at_ns),
        "road": {
            "lanes": int(msg.road.lanes),
            "lane_width_m": float(msg.road.lane_width_m),
            "speed_limit_mps": float(msg.road.speed_limit_mps),
        },
        "ego": {
            "x_m": float(msg.ego.x_m),
            "y_m": float(msg.ego.y_m),
            "v_mps": float(msg.ego.v_mps),
            "desired_speed_mps": float(msg.ego.desired_speed_mps),
            "maneuver": maneuver_to_json(msg.ego.maneuver),
        },
        "svs": [
            {
                "id": int(sv.id),
                "x_m": float(sv.x_m),
                "y_m": float(sv.y_m),
                "v_mps": float(sv.v_mps),
                "a_mps2": float(sv.a_mps2),
                "vy_mps": float(sv.vy_mps),
                "length_m": float(sv.length_m),
                "width_m": float(sv.width_m),
            }
            for sv in msg.svs
        ],
        "memory": memory_to_json(msg.memory),
    }


def decided_from_json(doc: Any, where: str = "outcome.decided") -> Decided:
    d = _fields(doc, where, ("action", "next_maneuver", "setpoint", "plan", "layer", "memory"))
    sp = _fields(d["setpoint"], _join(where, "setpoint"), ("accel_mps2", "target_speed_mps"))
    plan = []
    for i, step in enumerate(_list(d["plan"], MAX_HORIZON, _join(where, "plan"))):
        at = f"{where}.plan[{i}]"
        s = _fields(step, at, ("action", "maneuver", "x_m", "v_mps", "occupied_lanes"))
        plan.append(
            PlanStep(
                action=action_from_json(s["action"], _join(at, "action")),
                maneuver=maneuver_from_json(s["maneuver"], _join(at, "maneuver")),
                x_m=_f64(s["x_m"], _join(at, "x_m")),
                v_mps=_f64(s["v_mps"], _join(at, "v_mps")),
                occupied_lanes=_uint(s["occupied_lanes"], 16, _join(at, "occupied_lanes")),
            )
        )
    layer = d["layer"]
    if layer not in LAYER_CODES:
        raise ConversionError(f"{_join(where, 'layer')}: unknown layer {layer!r}")
    return Decided(
        action=action_from_json(d["action"], _join(where, "action")),
        next_maneuver=maneuver_from_json(d["next_maneuver"], _join(where, "next_maneuver")),
        setpoint=SetPoint(
            accel_mps2=_f64(sp["accel_mps2"], _join(where, "setpoint.accel_mps2")),
            target_speed_mps=_f64(
                sp["target_speed_mps"], _join(where, "setpoint.target_speed_mps")
            ),
        ),
        plan=plan,
        layer=LAYER_CODES[layer],
        memory=memory_from_json(d["memory"], _join(where, "memory")),
    )


def decided_to_json(msg: Decided) -> dict[str, Any]:
    if int(msg.layer) not in LAYER_NAMES:
        raise ConversionError(f"outcome.decided.layer: unknown code {int(msg.layer)}")
    return {
        "action": action_to_json(msg.action),
        "next_maneuver": maneuver_to_json(msg.next_maneuver),
        "setpoint": {
            "accel_mps2": float(msg.setpoint.accel_mps2),
            "target_speed_mps": float(msg.setpoint.target_speed_mps),
        },
        "plan": [
            {
                "action": action_to_json(s.action),
                "maneuver": maneuver_to_json(s.maneuver),
                "x_m": float(s.x_m),
                "v_mps": float(s.v_mps),
                "occupied_lanes": int(s.occupied_lanes),
            }
            for s in msg.plan
        ],
        "layer": LAYER_NAMES[int(msg.layer)],
        "memory": memory_to_json(msg.memory),
    }


def rejected_from_json(doc: Any, where: str = "outcome.rejected") -> Rejected:
    d = _fields(doc, where, ("reason", "field"))
    reason, field = d["reason"], d["field"]
    if reason not in REASON_CODES:
        raise ConversionError(f"{_join(where, 'reason')}: unknown reason {reason!r}")
    if not isinstance(field, str) or len(field) > MAX_FIELD_LEN:
        raise ConversionError(f"{_join(where, 'field')}: expected a string of <= 31 bytes")
    if any(not 1 <= ord(c) <= 127 for c in field):
        raise ConversionError(f"{_join(where, 'field')}: not ASCII 1..=127")
    return Rejected(reason=REASON_CODES[reason], field=field)


def rejected_to_json(msg: Rejected) -> dict[str, Any]:
    if int(msg.reason) not in REASON_NAMES:
        raise ConversionError(f"outcome.rejected.reason: unknown code {int(msg.reason)}")
    return {"reason": REASON_NAMES[int(msg.reason)], "field": str(msg.field)}


def response_from_json(doc: Any) -> PlanResponse:
    """A ``PlanResponse`` message from the protocol's JSON form (a dict).

    The outcome ``{"decided": {...}}`` / ``{"rejected": {...}}`` becomes ``outcome`` 0 / 1
    with that field filled (the other stays default); layer and reason names become their
    codes; ``signature`` (128 hex digits, or "" or omitted when unsigned) the uint8[64].
    """
    d = _fields(
        doc,
        "",
        ("version", "vehicle_id", "sequence", "solve_us", "queue_us", "outcome"),
        ("signature",),
    )
    outcome = d["outcome"]
    if not isinstance(outcome, dict) or len(outcome) != 1:
        raise ConversionError("outcome: expected an object with exactly one key")
    msg = PlanResponse(
        version=_uint(d["version"], 16, "version"),
        vehicle_id=_uint(d["vehicle_id"], 64, "vehicle_id"),
        sequence=_uint(d["sequence"], 64, "sequence"),
        solve_us=_uint(d["solve_us"], 32, "solve_us"),
        queue_us=_uint(d["queue_us"], 32, "queue_us"),
    )
    ((kind, body),) = outcome.items()
    if kind == "decided":
        msg.outcome = PlanResponse.OUTCOME_DECIDED
        msg.decided = decided_from_json(body)
    elif kind == "rejected":
        msg.outcome = PlanResponse.OUTCOME_REJECTED
        msg.rejected = rejected_from_json(body)
    else:
        raise ConversionError(f"outcome: unknown variant {kind!r}")
    msg.signature = list(signature_from_hex(d.get("signature", "")))
    return msg


def response_to_json(msg: PlanResponse) -> dict[str, Any]:
    """The protocol's JSON form of a ``PlanResponse`` message (only the outcome that holds)."""
    if msg.outcome == PlanResponse.OUTCOME_DECIDED:
        outcome = {"decided": decided_to_json(msg.decided)}
    elif msg.outcome == PlanResponse.OUTCOME_REJECTED:
        outcome = {"rejected": rejected_to_json(msg.rejected)}
    else:
        raise ConversionError(f"outcome: unknown code {int(msg.outcome)}")
    signature = bytes(int(b) for b in msg.signature)
    return {
        "version": int(msg.version),
        "vehicle_id": int(msg.vehicle_id),
        "sequence": int(msg.sequence),
        "solve_us": int(msg.solve_us),
        "queue_us": int(msg.queue_us),
        "outcome": outcome,
        "signature": signature.hex() if any(signature) else "",
    }


def signature_from_hex(text: Any) -> bytes:
    """The 64 signature bytes of the JSON form's hex string ("" = unsigned = all zeros)."""
    if not isinstance(text, str):
        raise ConversionError("signature: expected a string")
    if text == "":
        return bytes(SIGNATURE_LEN)
    try:
        raw = bytes.fromhex(text)
    except ValueError as err:
        raise ConversionError(f"signature: not hex ({err})") from None
    if len(raw) != SIGNATURE_LEN:
        raise ConversionError(f"signature: {len(raw)} bytes, expected {SIGNATURE_LEN}")
    return raw


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float written as "NaN", "inf" or "-inf" (recording style),
    so that ``json.dumps`` produces standard JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


# ---------------------------------------------------------------------------------------------
# CDR bytes
# ---------------------------------------------------------------------------------------------

_PRIMITIVE_SIZES = {
    "boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1,
    "int16": 2, "uint16": 2, "wchar": 2,
    "int32": 4, "uint32": 4, "float": 4,
    "int64": 8, "uint64": 8, "double": 8,
}  # fmt: skip


def _message_class(t: idl.NamespacedType) -> type:
    return getattr(importlib.import_module(".".join(t.namespaces)), t.name)


def cdr_padding_zeroed(msg_type: type, data: bytes) -> bytes:
    """``data`` (rclpy's ``serialize_message`` of a ``msg_type``) with every alignment padding
    byte set to zero.

    rclpy (Fast CDR) leaves padding bytes as they were in its buffer, so two serializations
    of one message can differ there (seen: 0x55, pointer fragments); a receiver ignores them.
    The walk follows the type (classic CDR, little endian, alignment counted after the 4-byte
    encapsulation header, 8-byte types 8-aligned), so the result is the canonical encoding
    with zero padding, including the trailing padding Fast DDS adds to fixed-size types.
    Raises ``ValueError`` when the bytes do not fit the type.
    """
    if data[:4] != b"\x00\x01\x00\x00":
        raise ValueError(f"not little-endian plain CDR: header {data[:4].hex()}")
    body = data[4:]
    keep = bytearray(len(body))  # 1 where a byte belongs to a value
    pos = 0

    def align(n: int) -> None:
        nonlocal pos
        pos = (pos + n - 1) // n * n

    def take(n: int) -> bytes:
        nonlocal pos
        if pos + n > len(body):
            raise ValueError(f"{msg_type.__name__}: CDR bytes end at {len(body)}, need {pos + n}")
        for i in range(pos, pos + n):
            keep[i] = 1
        chunk = body[pos : pos + n]
        pos += n
        return chunk

    def walk_type(t: idl.AbstractType) -> None:
        if isinstance(t, idl.BasicType):
            size = _PRIMITIVE_SIZES[t.typename]
            align(size)
            take(size)
        elif isinstance(t, idl.AbstractString):
            align(4)
            (length,) = struct.unpack("<I", take(4))
            take(length)  # the bytes and the terminating NUL
        elif isinstance(t, idl.AbstractWString):
            raise ValueError("wstring is not supported")
        elif isinstance(t, idl.NamespacedType):
            walk_struct(_message_class(t))
        elif isinstance(t, idl.Array):
            for _ in range(t.size):
                walk_type(t.value_type)
        elif isinstance(t, idl.AbstractSequence):
            align(4)
            (count,) = struct.unpack("<I", take(4))
            for _ in range(count):
                walk_type(t.value_type)
        else:
            raise ValueError(f"unsupported type {t!r}")

    def walk_struct(cls: type) -> None:
        for slot_type in cls.SLOT_TYPES:
            walk_type(slot_type)

    walk_struct(msg_type)
    if len(body) - pos >= 4:
        raise ValueError(f"{msg_type.__name__}: {len(body) - pos} bytes after the message")
    return data[:4] + bytes(b if k else 0 for b, k in zip(body, keep, strict=True))


def cdr_hex(msg: Any, raw: bool = False) -> str:
    """rclpy's CDR serialization of ``msg`` as hex, padding zeroed unless ``raw``."""
    data = serialize_message(msg)
    return (data if raw else cdr_padding_zeroed(type(msg), data)).hex()
