"""Publish a recording's inputs (camera images, IMU batches, LIDAR clouds, simulator truth) back on
the bus.

Payloads are the recorded bytes; each carries a fresh attachment with the recorded seq and stamp.
Modes: as recorded (default), `--rate N` (N times faster), `--fast` (as fast as the bus takes them)
or `--lock-step` (the next frame is released only once the pipeline answered the last; see
docs/recording.md).

Examples:
    atr replay runs/flight.mcap                  # at recorded speed
    atr replay runs/flight.mcap --rate 4 --zenoh compose/zenoh/local.json5
    atr replay runs/flight.mcap --lock-step --wait-for sfm --wait-for atr_matcher

"""

from __future__ import annotations

import argparse

from bus.service import add_zenoh_argument


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr replay`."""
    parser.add_argument("file", metavar="FILE", help="MCAP recording")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--rate", type=float, default=1.0, help="speed factor over the recorded spacing"
    )
    mode.add_argument("--fast", action="store_true", help="as fast as possible")
    mode.add_argument(
        "--lock-step", action="store_true", help="wait for the pipeline's answer to every frame"
    )
    add_zenoh_argument(parser)
    parser.add_argument("--uav", help="replay only this vehicle's inputs (default: all)")
    parser.add_argument(
        "--answer-key",
        default="atr/{uav}/detections",
        help="lock-step answer key ({uav} = the frame's vehicle)",
    )
    parser.add_argument(
        "--answer-timeout", type=float, default=60.0, help="lock-step wait per frame, s"
    )
    parser.add_argument(
        "--wait-for",
        action="append",
        default=[],
        metavar="SERVICE",
        help="wait for this service's Status before starting (repeatable)",
    )
    parser.add_argument(
        "--ready-timeout", type=float, default=30.0, help="how long to wait for --wait-for, s"
    )
    parser.add_argument(
        "--settle", type=float, default=0.3, help="pause before the first message, s"
    )


def run(args: argparse.Namespace) -> int:
    """Replay the file; returns 0, or 1 when lock-step answers timed out."""
    from bus.node import setup_logging
    from bus.replayer import Replayer
    from bus.stopping import stop_on_signals

    setup_logging("replayer")
    with Replayer(
        args.file,
        zenoh_config=args.zenoh,
        uav=args.uav,
        wait_for=args.wait_for,
        ready_timeout_s=args.ready_timeout,
        settle_s=args.settle,
    ) as replayer:
        stop_on_signals(replayer.stop)
        if args.lock_step:
            stats = replayer.lock_step(args.answer_key, args.answer_timeout)
        elif args.fast:
            stats = replayer.fast()
        else:
            stats = replayer.recorded(args.rate)
    mb = stats.bytes / 1e6
    summary = f"replayed {stats.published} messages ({mb:.1f} MB) in {stats.wall_s:.2f} s"
    if args.lock_step:
        summary += f"; {stats.answered}/{stats.frames} frames answered, {stats.timeouts} timeouts"
    print(summary)
    return 1 if stats.timeouts else 0
