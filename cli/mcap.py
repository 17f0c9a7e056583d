"""Inspect, check and repair MCAP recordings.

FILE is a recording's first segment: `flight.mcap` also reads `flight.1.mcap`, `flight.2.mcap`, ...
(what a restarted recorder writes) as one recording. `info` lists channels (topic, schema, message
count), the time span, message count and size; it warns on stderr and exits 1 when a segment was not
closed or a chunk cannot be read. `check` validates the file record by record (magic, schema and
channel definitions before use, chunk CRCs and sizes, indexes, summary and statistics against the
data, log-time order) and names every problem (exit 1), or prints OK. `recover` copies every
readable chunk of every segment (e.g. after a crash) into one clean file.

Examples:
    atr mcap info runs/flight.mcap
    atr mcap check runs/flight.mcap || echo "broken"
    atr mcap recover runs/crashed.mcap runs/crashed-recovered.mcap

"""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Sub-commands of `atr mcap`."""
    sub = parser.add_subparsers(dest="mcap_command", metavar="ACTION", required=True)
    info = sub.add_parser(
        "info", help="channels, counts, time span, size; exit 1 when the file has problems"
    )
    info.add_argument("file", metavar="FILE")
    check = sub.add_parser("check", help="validate a recording; exit 1 naming each problem")
    check.add_argument("file", metavar="FILE")
    recover = sub.add_parser(
        "recover", help="copy every readable chunk of a damaged or cut-short recording"
    )
    recover.add_argument("src", metavar="IN")
    recover.add_argument("dst", metavar="OUT")
    export = sub.add_parser(
        "export-foxglove",
        help="write a copy with Foxglove's schemas (images, clouds, poses, detections)",
    )
    export.add_argument("src", metavar="IN")
    export.add_argument("dst", metavar="OUT")


def _stamp(ns: int | None) -> str:
    import datetime

    if ns is None:
        return "-"
    if ns > 10**17:  # Unix epoch
        return datetime.datetime.fromtimestamp(ns / 1e9, datetime.UTC).isoformat(
            timespec="milliseconds"
        )
    return f"{ns / 1e9:.3f} s"


def run(args: argparse.Namespace) -> int:
    """Run one `atr mcap` action; returns its exit code."""
    from bus import mcap_tools

    if args.mcap_command == "info":
        info = mcap_tools.info(args.file)
        print(f"file:      {info.path}")
        if len(info.segments) > 1:
            print(f"segments:  {len(info.segments)} ({', '.join(info.segments)})")
        print(f"size:      {info.size_bytes / 1e6:.3f} MB{'' if info.closed else ' (not closed)'}")
        print(f"messages:  {info.messages} in {info.chunks} chunk(s)")
        print(
            f"span:      {_stamp(info.start_ns)} .. {_stamp(info.end_ns)} ({info.duration_s:.3f} s)"
        )
        print(f"channels:  {len(info.channels)}")
        width = max((len(c.topic) for c in info.channels), default=5)
        for c in info.channels:
            print(f"  {c.topic:<{width}}  {c.schema_name or '(no schema)':<12} {c.messages:>8}")
        for problem in info.problems:
            print(f"warning: {problem}", file=sys.stderr)
        if info.problems:
            print(
                f"warning: {len(info.problems)} problem(s): the counts above are what can be read; "
                "`atr mcap check` names them, `atr mcap recover` copies what is intact",
                file=sys.stderr,
            )
            return 1
        return 0
    if args.mcap_command == "check":
        problems = mcap_tools.check(args.file)
        for problem in problems:
            print(f"{args.file}: {problem}")
        if problems:
            return 1
        print("OK")
        return 0
    if args.mcap_command == "export-foxglove":
        from bus.foxglove_export import export_foxglove

        counts = export_foxglove(args.src, args.dst)
        for topic, n in sorted(counts.items()):
            print(f"  {topic:<28} {n:>6}")
        print(f"wrote {sum(counts.values())} messages to {args.dst}")
        return 0
    result = mcap_tools.recover(args.src, args.dst)
    segments = f" in {result.segments} segments" if result.segments > 1 else ""
    print(
        f"recovered {result.messages} messages on {result.channels} channels from "
        f"{result.readable_bytes}/{result.source_bytes} bytes{segments} into {args.dst}"
    )
    for problem in result.problems:
        print(f"skipped: {problem}")
    return 0
