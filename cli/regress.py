"""Replay every recording of a corpus through the current code and diff each against its baseline.

Each recording (`CORPUS_DIR/NAME.mcap`, replayed with the current defaults, then the config groups of `NAME.yml`
if present: every setting its baseline was made with that is not a default, e.g. `sfm: {matcher: gftt}`) goes
through the service graph in lock-step as `atr run` does, on its own hub port; the replay is compared with
`BASELINE/NAME.mcap` as `atr diff` compares. The replays are tasks on Dask distributed: a LocalCluster of
worker processes (one per 2 cores: each replay starts a whole service graph) or the scheduler at
`--scheduler ADDRESS`. `--update` makes the replays the new baselines and writes beside each
`NAME.json`: the code version (git describe and a hash of the sources) and the config it was made with.

Exit codes: 0 every recording is the same as its baseline (or the baselines were updated), 1 one differs,
has no baseline or its replay failed, 2 error (bad arguments, empty corpus, bad tolerance file).

Examples:
    atr regress recordings --baseline recordings/baselines
    atr regress recordings --baseline recordings/baselines --set recognition.descriptor=fpfh
    atr regress recordings --baseline recordings/baselines --update
    atr regress recordings --baseline recordings/baselines --junit regress.xml --scheduler tcp://10.0.0.5:8786

"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from bus.service import add_overrides_argument


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr regress`."""
    parser.add_argument(
        "corpus", type=Path, help="directory of recordings (*.mcap, optional NAME.yml)"
    )
    parser.add_argument("--baseline", type=Path, required=True, help="directory of the baselines")
    parser.add_argument("--update", action="store_true", help="make the replays the new baselines")
    parser.add_argument("--junit", type=Path, metavar="FILE", help="write JUnit XML")
    parser.add_argument("--tolerances", type=Path, metavar="FILE.yml", help="tolerance rules")
    parser.add_argument(
        "--scheduler", metavar="ADDRESS", help="Dask scheduler (default: a LocalCluster here)"
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=max(1, (os.cpu_count() or 2) // 2),
        help="LocalCluster worker processes (default: one per 2 cores)",
    )
    parser.add_argument("--work", type=Path, help="where replays are written (default: a temp dir)")
    parser.add_argument("--layout", default="local", help="layout name in compose/ or a file")
    add_overrides_argument(parser, "config override passed to every service (repeatable)")


def replay_task(
    recording: str,
    out: str,
    overrides: list[str],
    layout: str,
    baseline: str | None,
    tolerances: Any,
) -> dict[str, Any]:
    """One corpus recording replayed (and diffed against `baseline` when given): a Dask task."""
    from bus.diff import diff_recordings
    from bus.pipeline import run_recording

    result = run_recording(Path(recording), Path(out), layout=layout, overrides=overrides)
    report = None
    if baseline is not None and result.frames and Path(out).is_file():
        report = diff_recordings(baseline, out, tolerances)
    return {
        "frames": result.frames,
        "timeouts": result.timeouts,
        "failures": result.failures,
        "log_dir": str(result.log_dir),
        "report": report,
    }


def _replay_all(
    client: Any, entries: list[Any], args: argparse.Namespace, work: Path, tolerances: Any
) -> list[dict[str, Any]]:
    """Every corpus recording replayed as a task on the Dask client; their results in corpus order."""
    futures = []
    for entry in entries:
        baseline = args.baseline / f"{entry.name}.mcap"
        compare_with = str(baseline) if baseline.is_file() and not args.update else None
        futures.append(
            client.submit(
                replay_task,
                str(entry.path.resolve()),
                str((work / f"{entry.name}.mcap").resolve()),
                list(entry.overrides),
                args.layout,
                compare_with,
                tolerances,
                key=f"replay-{entry.name}",
                pure=False,
            )
        )
    return client.gather(futures)


def run(args: argparse.Namespace) -> int:
    """Replay the corpus, print a table, write JUnit; see the module docstring for exit codes."""
    import json
    import shutil
    import tempfile
    from contextlib import ExitStack

    from atr.errors import AtrError, ConfigError
    from atr.regression.corpus import baseline_provenance, load_corpus
    from atr.regression.tolerances import load_tolerances
    from atr.scaleout import dask_client

    with ExitStack() as stack:
        try:
            entries = load_corpus(args.corpus, args.overrides)
            tolerances = load_tolerances(args.tolerances)
            work = args.work or Path(tempfile.mkdtemp(prefix="atr-regress-"))
            work.mkdir(parents=True, exist_ok=True)
            args.baseline.mkdir(parents=True, exist_ok=True)
            if args.workers < 1:
                raise ConfigError(f"--workers {args.workers} must be >= 1")
            client = stack.enter_context(dask_client(args.scheduler, args.workers))
        except AtrError as exc:
            print(f"atr regress: {exc}", file=sys.stderr)
            return 2
        results = _replay_all(client, entries, args, work, tolerances)
    rows, suites, failed = [], [], False
    for entry, result in zip(entries, results, strict=True):
        verdict, detail, suite = _judge(entry, result, args)
        failed |= verdict not in ("same", "updated")
        if verdict == "updated":
            shutil.copyfile(work / f"{entry.name}.mcap", args.baseline / f"{entry.name}.mcap")
            provenance = baseline_provenance(entry, args.layout, result["frames"])
            (args.baseline / f"{entry.name}.json").write_text(
                json.dumps(provenance, indent=2, sort_keys=True, default=str) + "\n"
            )
        rows.append((entry.name, str(result["frames"]), verdict, detail))
        suites.append(suite)
    _print_table(rows)
    if args.junit is not None:
        from atr.regression.report import write_junit

        try:
            write_junit(suites, args.junit)
        except AtrError as exc:
            print(f"atr regress: {exc}", file=sys.stderr)
            return 2
    if failed:
        print(f"replays kept in {work}; `atr diff BASELINE REPLAY` shows one in full")
    elif args.work is None:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failed else 0


def _judge(entry: Any, result: dict[str, Any], args: argparse.Namespace) -> tuple[str, str, Any]:
    """Verdict, one-line detail and JUnit testsuite of one replayed recording."""
    import xml.etree.ElementTree as ET

    from atr.regression.report import junit_suite

    name = f"atr regress {entry.name}"
    report = result["report"]
    suite = junit_suite(report, name) if report is not None else ET.Element("testsuite", name=name)
    case = ET.Element("testcase", classname=name, name="replay")
    suite.insert(0, case)
    suite.set("tests", str(int(suite.get("tests", "0")) + 1))
    problem = ""
    if result["failures"]:
        problem = f"processes failed {result['failures']}; logs in {result['log_dir']}"
    elif result["timeouts"] or not result["frames"]:
        problem = f"{result['timeouts']} of {result['frames']} frames unanswered"
    elif not args.update and report is None:
        problem = f"no baseline {args.baseline / (entry.name + '.mcap')}; make one with --update"
    if problem:
        ET.SubElement(case, "failure", message=problem)
        suite.set("failures", str(int(suite.get("failures", "0")) + 1))
        return "FAILED", problem, suite
    if args.update:
        return "updated", f"baseline {args.baseline / (entry.name + '.mcap')}", suite
    if report.same:
        return "same", "", suite
    first = report.differing_topics[0]
    where = f"{first.topic}: {first.first[1].describe()}" if first.first else first.summary()
    more = len(report.differing_topics) - 1
    return "DIFFERS", where + (f" (+{more} topics)" if more else ""), suite


def _print_table(rows: list[tuple[str, str, str, str]]) -> None:
    header = ("recording", "frames", "result", "first difference")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(3)]
    for row in [header, *rows]:
        print("  ".join(cell.ljust(width) for cell, width in zip(row[:3], widths)) + "  " + row[3])
