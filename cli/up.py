"""Start a deployment layout from compose/ and keep it running until Ctrl-C or SIGTERM.

A process that fails is restarted with exponential back-off; one that exits 0 has finished (a source at the
end of its flight) and is not. Ctrl-C, SIGTERM or SIGHUP stops everything (the recorder last, so its file
closes cleanly). Relative paths in --var out=... and --var deploy=... are the caller's working directory's.
The recording goes to runs/up-<time>/flight.mcap unless --var out=... names another file (never an existing
one: a recording is never overwritten).

Examples:
    atr up                                    # compose/local.yml
    atr up local --var out=runs/today.mcap --set recognition.descriptor=fpfh
    atr up split --host ground                # only the ground host's processes

"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bus.service import add_overrides_argument


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr up`."""
    parser.add_argument(
        "layout", nargs="?", default="local", help="layout name in compose/ or a file"
    )
    parser.add_argument(
        "--var", action="append", default=[], metavar="NAME=VALUE", help="layout variable"
    )
    add_overrides_argument(parser, "config override passed to every pipeline service (repeatable)")
    parser.add_argument(
        "--host", action="append", help="start only the processes of this host (repeatable)"
    )
    parser.add_argument("--no-source", action="store_true", help="leave out the sensor source")


def parse_vars(pairs: list[str]) -> dict[str, str]:
    """NAME=VALUE strings as a dict."""
    from atr.errors import ConfigError

    out = {}
    for pair in pairs:
        if "=" not in pair:
            raise ConfigError(f"layout variable {pair!r} must look like NAME=VALUE")
        name, value = pair.split("=", 1)
        out[name] = value
    return out


def run(args: argparse.Namespace) -> int:
    """Run the layout until stopped (SIGTERM, SIGINT or SIGHUP stop every process it started)."""
    import logging

    from atr.config import load_config
    from atr.errors import ConfigError
    from bus.launcher import Supervisor, load_layout, on_stop_signals, user_variables
    from bus.node import setup_logging
    from bus.pipeline import check_output
    from bus.stopping import StopRequest

    # everything is checked before a process starts: a bad --set would crash-loop every service
    variables = parse_vars(args.var)
    # a fresh recording per `atr up`: a recorder that finds its file continues it as a segment, which
    # is right after a crash and wrong for a new flight
    folder = time.strftime("runs/up-%Y%m%d-%H%M%S")
    variables.setdefault("out", f"{folder}/flight.mcap")
    variables.setdefault("air_out", f"{folder}/air.mcap")  # the split layout's aircraft recording
    variables = user_variables(variables)
    check_output(Path(variables["out"]))
    layout = load_layout(args.layout, variables)
    load_config(None, args.overrides)
    hosts = {p.host for p in layout.processes}
    unknown = sorted(set(args.host or ()) - hosts)
    if unknown:
        raise ConfigError(
            f"--host {unknown} not in layout {layout.name!r}; its hosts: {sorted(hosts)}"
        )
    setup_logging("up")
    supervisor = Supervisor(
        layout,
        overrides=args.overrides,
        hosts=tuple(args.host) if args.host else None,
        skip_roles=("source",) if args.no_source else (),
    )
    stop = StopRequest()
    on_stop_signals(stop.set)
    try:
        supervisor.start()
        logging.getLogger("atr").info(
            "layout %s up: %s", layout.name, [p.name for p in supervisor.specs]
        )
        while not stop.wait(0.5):
            supervisor.poll()
    finally:
        supervisor.stop()
    return 0
