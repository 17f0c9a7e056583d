"""Simulate one scenario run of Table II straight into an MCAP recording (no bus needed).

The recording holds what sensor_source would publish — images, IMU batches, LIDAR scans (with --lidar) and
truth — on the same keys, so `atr run` can replay it through the service graph.

The target is the T-72 unless --target names another vehicle of the family (`atr world export --help` lists them)
or --target-mesh gives a mesh file; --clutter and --clutter-mesh add confusers (docs/sim.md, "Vehicles").

Examples:
    atr simulate --scenario 1 --run 3 --frames 20 --out flight.mcap
    atr simulate --scenario 3 --run 1 --lidar --noise gaussian:10 --out s3.mcap
    atr simulate --scenario 2 --run 1 --target leopard2 --clutter t72 --clutter m1 --out leopard.mcap
    atr simulate --scenario 2 --run 1 --target-mesh my_tank.stl:units=mm --out custom.mcap

"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr simulate`."""
    from bus.flight_messages import add_flight_arguments
    from bus.service import add_overrides_argument
    from cli.world import add_vehicle_arguments

    add_flight_arguments(parser)
    add_vehicle_arguments(parser)
    parser.add_argument("--uav", default="uav1", help="vehicle id in the keys")
    add_overrides_argument(parser)
    parser.add_argument("--out", type=Path, required=True, help="output MCAP file")


def run(args: argparse.Namespace) -> int:
    """Simulate and record."""
    from atr.config import load_config
    from atr.io.mesh import vehicle_sources
    from bus.flight_messages import flight_frame_messages, flight_frames
    from bus.recording import write_messages

    config = load_config(None, args.overrides)
    args.target_mesh, args.clutter_mesh = vehicle_sources(
        args.target, args.target_mesh, args.clutter, args.clutter_mesh
    )
    frames = flight_frames(config, args)

    messages = (m for _, sent in flight_frame_messages(config, args, frames) for m in sent)
    count = write_messages(args.out, messages)
    print(f"wrote {count} messages to {args.out}")
    return 0
