"""Audit a recording: which software and configuration made it, whether anything is missing, every
decision with its evidence, errors by service, and whether the file was closed cleanly.

Exit 0 when the recording is complete and consistent, 1 naming each problem (lost messages, a cut
file, frames without an answer, no provenance), 2 when the file cannot be read. A recording continued
in segments after a recorder restart is audited as one (give the first file). `--html` writes one
self-contained page with a figure of the flight (docs/recording.md, "Auditing").

Examples:
    atr audit runs/flight.mcap
    atr audit runs/flight.mcap --html runs/flight-audit.html --json runs/flight-audit.json

"""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr audit`."""
    parser.add_argument("file", help="the MCAP recording (its first segment)")
    parser.add_argument("--html", metavar="OUT", help="write the audit as one HTML page")
    parser.add_argument("--json", metavar="OUT", help="write the audit's findings as JSON")


def run(args: argparse.Namespace) -> int:
    """Audit; print the findings; return 0 complete, 1 problems, 2 unreadable."""
    import json
    from collections import Counter
    from pathlib import Path

    from atr.errors import AtrError
    from bus.audit import audit, render_html

    try:
        report = audit(args.file)
    except AtrError as exc:
        print(f"atr audit: {exc}", file=sys.stderr)
        return 2
    for i, prov in enumerate(report.provenance):
        shown = {k: prov.get(k) for k in ("package_version", "source_commit", "config_sha256")}
        print(f"segment {i}: " + ", ".join(f"{k} {v}" for k, v in shown.items()))
    lost = sum(p.lost() for p in report.publishers.values())
    print(f"{len(report.publishers)} publishers, {lost} messages lost, {report.frames} frames")
    print(
        f"{len(report.decisions)} decisions; errors by service: {dict(Counter(s for _, s, _ in report.errors))}"
    )
    for change in report.config_changes:
        print(f"configuration change: {change}")
    for out, text in (
        (args.html, lambda: render_html(report)),
        (args.json, lambda: json.dumps(report.summary(), indent=1)),
    ):
        if out:
            try:
                Path(out).write_text(text())
            except OSError as exc:
                print(f"atr audit: cannot write {out}: {exc}", file=sys.stderr)
                return 2
    if not report.problems:
        print("complete and consistent")
        return 0
    for problem in report.problems:
        print(f"PROBLEM: {problem}")
    return 1
