"""Run one service by name: what the layouts in compose/ start, one process each.

Examples:
    atr service sfm --uav uav1 --set sfm.matcher=surf
    atr service router --listen tcp/127.0.0.1:7447
    atr service atr_matcher --help

"""

from __future__ import annotations

import argparse
import importlib
import pkgutil

import services


def available() -> list[str]:
    """Names of the services in services/."""
    return sorted(m.name for m in pkgutil.iter_modules(services.__path__) if m.ispkg)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr service`."""
    parser.add_argument("name", help=f"one of: {', '.join(available())}")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the service's own arguments")


def run(args: argparse.Namespace) -> int:
    """Start the service in this process."""
    if args.name not in available():
        raise SystemExit(f"unknown service {args.name!r}; expected one of {available()}")
    module = importlib.import_module(f"services.{args.name}.main")
    return int(module.main(args.args) or 0)
