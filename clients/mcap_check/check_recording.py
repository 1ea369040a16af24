#!/usr/bin/env python3
"""Reads an MCAP recording with the reference `mcap` package (PyPI), independently of the
Rust writer, and prints what it holds as JSON: per channel the schema, the encodings, the
message count, the (vehicle_id, sequence) pairs of plan messages, and every schema-required
top-level field missing from a message.

    python3 check_recording.py FILE.mcap
"""

import json
import sys

from mcap.reader import make_reader


def main(path):
    channels = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            schema_doc = json.loads(schema.data) if schema is not None else {}
            channels[channel.topic] = {
                "schema_name": schema.name if schema else None,
                "schema_encoding": schema.encoding if schema else None,
                "schema_title": schema_doc.get("title"),
                "message_encoding": channel.message_encoding,
                "required": schema_doc.get("required", []),
                "count": 0,
                "ids": [],
                "missing_fields": [],
                "log_times_ordered": True,
                "_last": 0,
            }
        statistics_count = summary.statistics.message_count if summary.statistics else None
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            entry = channels[channel.topic]
            entry["count"] += 1
            doc = json.loads(message.data)
            for field in entry["required"]:
                if field not in doc:
                    entry["missing_fields"].append(field)
            if "vehicle_id" in doc and "sequence" in doc:
                entry["ids"].append([doc["vehicle_id"], doc["sequence"]])
            if channel.topic != "/planner/request" and channel.topic != "/planner/response":
                # Answers are written as they are given, not in arrival order.
                if message.log_time < entry["_last"]:
                    entry["log_times_ordered"] = False
                entry["_last"] = message.log_time
    for entry in channels.values():
        del entry["_last"]
    print(json.dumps({"channels": channels, "statistics_message_count": statistics_count}))


if __name__ == "__main__":
    main(sys.argv[1])
