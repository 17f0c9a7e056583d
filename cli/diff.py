"""Compare the data messages of two recordings and say exactly what changed (docs/regression.md).

Messages are aligned per topic by frame (stamp_ns, then order); equal bytes are the same without decoding,
others are decoded and compared field by field: exactly, unless a tolerance file accepts a difference.
Detections are compared as what they mean (same targets; pose difference in metres and degrees; score).
Status and Timing topics and the input_source of ErrorReports (wall clock, process ids) are ignored.

Exit codes: 0 the same (within tolerances), 1 they differ, 2 error (unreadable file, schema mismatch,
bad tolerance file or arguments).

Examples:
    atr diff baseline.mcap new.mcap
    atr diff baseline.mcap new.mcap --tolerances tolerances.yml --junit diff.xml --jsonl frames.jsonl

"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXIT_SAME, EXIT_DIFFER, EXIT_ERROR = 0, 1, 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr diff`."""
    parser.add_argument("base", type=Path, help="the reference recording (a baseline)")
    parser.add_argument("new", type=Path, help="the recording under test")
    parser.add_argument(
        "--tolerances",
        type=Path,
        metavar="FILE.yml",
        help="YAML tolerance rules per topic and field",
    )
    parser.add_argument(
        "--junit", type=Path, metavar="FILE", help="write JUnit XML: a testcase per topic"
    )
    parser.add_argument("--jsonl", type=Path, metavar="FILE", help="write one JSON line per frame")


def run(args: argparse.Namespace) -> int:
    """Compare and print the summary; 0 same, 1 differ, 2 error (printed, never a traceback)."""
    from atr.errors import AtrError
    from atr.regression.report import junit_suite, write_jsonl, write_junit
    from atr.regression.tolerances import load_tolerances
    from bus.diff import diff_recordings

    try:
        report = diff_recordings(args.base, args.new, load_tolerances(args.tolerances))
        if args.junit is not None:
            write_junit(
                [junit_suite(report, f"atr diff {args.base.name} {args.new.name}")], args.junit
            )
        if args.jsonl is not None:
            write_jsonl(report, args.jsonl)
    except AtrError as exc:
        print(f"atr diff: {exc}", file=sys.stderr)
        return EXIT_ERROR
    print(report.summary())
    return EXIT_SAME if report.same else EXIT_DIFFER
