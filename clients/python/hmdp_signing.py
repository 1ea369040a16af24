"""Checking the planner's signature on a PlanResponse (docs/protocol.md, "Authentication").

The signature covers the response's bincode encoding without the signature itself, whatever
form carried the response: a client that reads JSON re-encodes it here, field by field, in
the layout docs/protocol.md gives ("bincode form"). Needs the `cryptography` package (see
requirements.txt), imported only when a key is read.
"""

import ipaddress
import re
import socket
import struct

SIGNATURE_LENGTH = 64

# Codes of the enumerations (docs/protocol.md, "Enumerations").
LAYER_CODES = {
    "nominal": 0,
    "global_relaxation": 1,
    "fallback": 2,
    "watchdog_fallback": 3,
    "stale_fallback": 4,
}
REASON_CODES = {
    "unsupported_version": 1,
    "capacity_exceeded": 2,
    "non_finite": 10,
    "out_of_range": 11,
    "negative_speed": 12,
    "lane_count": 13,
    "lane_out_of_range": 14,
    "beta_out_of_range": 15,
    "duplicate_sv_id": 16,
    "too_many_vehicles": 17,
    "invalid_memory": 18,
    "malformed": 30,
    "overloaded": 31,
    "internal_error": 32,
}


class SignatureError(Exception):
    """An answer that does not carry the planner's signature: refused, never acted on."""


class Unsigned(SignatureError):
    """The answer carries no signature."""


class BadSignature(SignatureError):
    """The signature is not the planner's signature of this answer (forged or altered)."""


def _action(a):
    return struct.pack("<bb", a["lateral"], a["longitudinal"])


def _maneuver(m):
    return struct.pack("<Bb", m["lane"], m["beta"])


def _memory(m):
    out = struct.pack("<Q", len(m["corrective"]))
    for e in m["corrective"]:
        out += struct.pack("<Idd", e["sv_id"], e["release_m"], e["trigger_m"])
    out += struct.pack("<Q", len(m["previous_plan"]))
    for a in m["previous_plan"]:
        out += _action(a)
    return out


def signed_bytes(response):
    """The bytes the planner signed: the bincode encoding of `response` (a decoded JSON
    PlanResponse) up to its signature. KeyError / struct.error on a response that is not
    well formed."""
    out = struct.pack(
        "<HQQII",
        response["version"],
        response["vehicle_id"],
        response["sequence"],
        response["solve_us"],
        response["queue_us"],
    )
    outcome = response["outcome"]
    if "decided" in outcome:
        d = outcome["decided"]
        out += struct.pack("<I", 0) + _action(d["action"]) + _maneuver(d["next_maneuver"])
        out += struct.pack("<dd", d["setpoint"]["accel_mps2"], d["setpoint"]["target_speed_mps"])
        out += struct.pack("<Q", len(d["plan"]))
        for step in d["plan"]:
            out += _action(step["action"]) + _maneuver(step["maneuver"])
            out += struct.pack("<ddH", step["x_m"], step["v_mps"], step["occupied_lanes"])
        out += struct.pack("<B", LAYER_CODES[d["layer"]]) + _memory(d["memory"])
    else:
        r = outcome["rejected"]
        field = r["field"].encode("ascii")
        out += struct.pack("<IBQ", 1, REASON_CODES[r["reason"]], len(field)) + field
    return out


class Verifier:
    """The planner's public key: `verify(response)` raises a SignatureError unless the
    response carries the planner's signature of its own bytes."""

    def __init__(self, public_key_hex):
        from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

        raw = bytes.fromhex(public_key_hex.strip())
        if len(raw) != 32:
            raise ValueError("an Ed25519 public key is 32 bytes (64 hex digits)")
        self._key = Ed25519PublicKey.from_public_bytes(raw)

    @classmethod
    def from_file(cls, path):
        with open(path, encoding="ascii") as f:
            return cls(f.read())

    def verify(self, response):
        from cryptography.exceptions import InvalidSignature

        signature = response.get("signature", "")
        if not signature:
            raise Unsigned("the answer is not signed")
        try:
            raw = bytes.fromhex(signature)
            if len(raw) != SIGNATURE_LENGTH:
                raise ValueError("wrong length")
            self._key.verify(raw, signed_bytes(response))
        except (ValueError, KeyError, TypeError, struct.error, InvalidSignature) as e:
            raise BadSignature("the answer's signature does not verify with the planner's key") from e


class UnverifiedPlanner(Exception):
    """A planner beyond this host whose answers could not be verified (no public key)."""


def endpoint_is_loopback(endpoint):
    """Whether a Zenoh endpoint (``tcp/HOST:PORT``, ``tls/...``, ``unixsock-stream/PATH``)
    stays on this host: a Unix socket, a loopback address, or a name that resolves to
    loopback addresses only. A name that does not resolve counts as beyond (the Rust rule,
    transport::zenoh::security::is_loopback_endpoint)."""
    locator = re.split(r"[?#]", endpoint, maxsplit=1)[0]
    protocol, _, address = locator.partition("/")
    if protocol in ("unixsock-stream", "unixpipe"):
        return True
    if protocol not in ("tcp", "tls", "udp", "quic", "ws"):
        return False
    host, _, port = address.rpartition(":")
    host = host.strip("[]")
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, int(port))
    except (OSError, ValueError):
        return False
    return bool(infos) and all(ipaddress.ip_address(info[4][0]).is_loopback for info in infos)


def check_endpoint(endpoint, verified, insecure):
    """Unsigned answers are safe only on this host: beyond it, anyone who can answer on the
    Zenoh network would be believed. Raises UnverifiedPlanner for a planner beyond this host
    without a key (`verified` false) unless `insecure`; returns the warning to log loudly
    in that case, else None."""
    if verified or endpoint_is_loopback(endpoint):
        return None
    if not insecure:
        raise UnverifiedPlanner(
            f"the planner at {endpoint} is beyond this host and its answers cannot be verified: "
            "give its public key with --planner-key FILE.pub, or accept unverified answers with --insecure"
        )
    return (
        f"INSECURE: answers from the planner at {endpoint} are not verified: anyone who can answer on "
        "that network commands this vehicle; give the planner's public key (--planner-key)"
    )
