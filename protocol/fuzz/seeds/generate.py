#!/usr/bin/env python3
"""Writes the seed corpora from the examples in docs/protocol.md.

The hex dump and the JSON blocks there are checked against the encoder by
protocol/tests/docs.rs, so the seeds are real messages. Run from anywhere:
    python3 protocol/fuzz/seeds/generate.py
"""
import hashlib
import json
import pathlib
import re

HERE = pathlib.Path(__file__).resolve().parent
DOC = HERE.parents[2] / "docs" / "protocol.md"


def block(text, name):
    m = re.search(rf"<!-- {name}:begin -->\n```\w*\n(.*?)```\n<!-- {name}:end -->", text, re.S)
    if not m:
        raise SystemExit(f"block {name} not found in {DOC}")
    return m.group(1)


def main():
    doc = DOC.read_text()
    request = bytes.fromhex(block(doc, "hex-example").replace("\n", " "))
    json_request = json.loads(block(doc, "json-request"))

    out = HERE / "decode_request"
    out.mkdir(exist_ok=True)
    seeds = {
        "request.bin": request,
        "request.json": json.dumps(json_request, separators=(",", ":")).encode(),
        "request-pretty.json": json.dumps(json_request, indent=2).encode(),
        # Optional fields left out.
        "request-minimal.json": json.dumps(
            {k: v for k, v in json_request.items() if k not in ("deadline_us", "sent_at_ns", "memory")}
        ).encode(),
        "response.json": block(doc, "json-response").encode(),
        "rejection.json": block(doc, "json-rejection").encode(),
    }
    for name, data in seeds.items():
        (out / name).write_bytes(data)

    # decide_valid reads its input through `arbitrary`: any bytes are a request. A few fixed
    # pseudo-random strings of different lengths give it a start.
    out = HERE / "decide_valid"
    out.mkdir(exist_ok=True)
    for n in (64, 256, 1024):
        data = b"".join(hashlib.sha256(f"{n}:{i}".encode()).digest() for i in range(n // 32))
        (out / f"random-{n}").write_bytes(data)


if __name__ == "__main__":
    main()
