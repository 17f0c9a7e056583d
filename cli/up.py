"""Start a deployment layout from compose/ and keep it running until Ctrl-C or SIGTERM.

A process that dies is restarted with exponential back-off; Ctrl-C stops everything (the recorder last, so
its file closes cleanly).

Examples:
    atr up                                    # compose/local.yml
    atr up local --var out=runs/today.mcap --set recognition.descriptor=fpfh
    atr up split --host ground                # only the ground host's processes

"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr up`."""
    parser.add_argument(
        "layout", nargs="?", default="local", help="layout name in compose/ or a file"
    )
    parser.add_argument(
        "--var", action="append", default=[], metavar="NAME=VALUE", help="layout variable"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="GROUP.FIELD=VALUE",
        help="config override passed to every pipeline service",
    )
    parser.add_argument(
        "--host", action="append", help="start only the processes of this host (repeatable)"
    )
    parser.add_argument("--no-source", action="store_true", help="leave out the sensor source")


def parse_vars(pairs: list[str]) -> dict[str, str]:
    """NAME=VALUE strings as a dict."""
    from atr.errors import ConfigError  # noqa: PLC0415

    out = {}
    for pair in pairs:
        if "=" not in pair:
            raise ConfigError(f"layout variable {pair!r} must look like NAME=VALUE")
        name, value = pair.split("=", 1)
        out[name] = value
    return out


def run(args: argparse.Namespace) -> int:
    """Run the layout until stopped."""
    import logging  # noqa: PLC0415

    from bus.launcher import Supervisor, load_layout  # noqa: PLC0415
    from bus.node import setup_logging  # noqa: PLC0415
    from bus.stopping import StopRequest, stop_on_signals  # noqa: PLC0415

    setup_logging("up")
    layout = load_layout(args.layout, parse_vars(args.var))
    supervisor = Supervisor(
        layout,
        overrides=args.overrides,
        hosts=tuple(args.host) if args.host else None,
        skip_roles=("source",) if args.no_source else (),
    )
    stop = StopRequest()
    stop_on_signals(stop.set)
    supervisor.start()
    logging.getLogger("atr").info(
        "layout %s up: %s", layout.name, [p.name for p in supervisor.specs]
    )
    while not stop.wait(0.5):
        supervisor.poll()
    supervisor.stop()
    return 0
