"""Replay a recording through a layout in lock-step and record everything: the regression command.

It starts the layout without its sensor source, waits until every service is ready, replays INPUT's sensor
messages in lock-step (the next frame only after the pipeline has answered the last; with --rate, at the
camera's pace times RATE whether or not it has), records all traffic to
OUTPUT, stops the layout, and exits non-zero naming any process that failed. The same recording and config
give byte-identical data messages (docs/architecture.md). A simulated flight's recording carries its truth; the
run's F1 (§III-C, judged as `atr eval` judges it) is printed then.

Examples:
    atr run flight.mcap --out result.mcap
    atr run flight.mcap --out fpfh.mcap --set recognition.descriptor=fpfh
    atr run flight.mcap --out paper.mcap --preset paper
    atr run flight.mcap --out surf.mcap --set sfm.matcher=surf --layout local
    atr run flight.mcap --out paced.mcap --rate 2      # frames at twice the camera's pace, no lock-step

"""

from __future__ import annotations

import argparse
from pathlib import Path

from bus.service import add_overrides_argument


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr run`."""
    parser.add_argument("input", type=Path, help="recording whose sensor messages are replayed")
    parser.add_argument("--out", type=Path, required=True, help="recording of the whole run")
    parser.add_argument("--layout", default="local", help="layout name in compose/ or a file")
    add_overrides_argument(parser, "config override passed to every service (repeatable)")
    parser.add_argument(
        "--answer-timeout", type=float, default=600.0, help="lock-step wait per frame, s"
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=None,
        help="send the frames at RATE x the recorded pace, not in lock-step (throughput and latency; "
        "a service that falls behind drops inputs and says so)",
    )
    parser.add_argument(
        "--ready-timeout",
        type=float,
        default=900.0,
        help="wait for services to be ready (first template build included), s",
    )


def run(args: argparse.Namespace) -> int:
    """Run the replay; 0 when every process stayed up and every frame was answered."""
    from atr.errors import ConfigError
    from bus.launcher import interrupt_on_signals
    from bus.pipeline import check_output, run_recording
    from cli.flight_report import f1_line, summarise, summarise_tracks, track_line

    # run_recording checks the input, the layout and the overrides before anything starts
    for flag, value in (
        ("--answer-timeout", args.answer_timeout),
        ("--ready-timeout", args.ready_timeout),
        ("--rate", 1.0 if args.rate is None else args.rate),
    ):
        if not value > 0:
            raise ConfigError(f"{flag} {value} must be > 0 seconds")
    args.out = check_output(args.out)  # the user's working directory, not the services' folder
    with interrupt_on_signals():  # SIGTERM/SIGHUP stop the layout as Ctrl-C does
        result = run_recording(
            args.input,
            args.out,
            layout=args.layout,
            overrides=args.overrides,
            answer_timeout_s=args.answer_timeout,
            ready_timeout_s=args.ready_timeout,
            rate=args.rate,
        )
    print(f"replayed {result.frames} frames ({result.timeouts} unanswered) into {args.out}")
    counts = summarise(args.out) if result.frames and not result.failures else None
    if counts is not None:  # a simulated flight: judged against its truth as `atr eval` judges it
        print(f1_line(counts))
        tracks = summarise_tracks(args.out)
        if tracks is not None:
            print(track_line(tracks))
    for name, codes in result.failures.items():
        print(
            f"process {name} failed with exit codes {codes}; see {result.log_dir / (name + '.log')}"
        )
    return 1 if result.failures or result.timeouts else 0
