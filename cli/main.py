"""The `atr` command: a thin shell that maps sub-commands onto the modules that implement them.

Each sub-command lives in `cli/<module>.py` with `add_arguments(parser)` and `run(args) -> int`.
Heavy imports stay inside `run`, so `atr --help` is instant.

Examples:
    atr demo                                   # simulated flight end to end over the bus
    atr simulate --scenario 1 --run 3 --frames 20 --out flight.mcap
    atr run flight.mcap --out result.mcap      # replay in lock-step through the service graph

"""

from __future__ import annotations

import argparse
import importlib
import sys
from importlib.metadata import PackageNotFoundError, version

from atr.errors import AtrError

# name -> (module under cli/, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("demo", "simulate a short flight and run the whole service graph over Zenoh"),
    "simulate": ("simulate", "simulate a scenario run straight into an MCAP recording"),
    "world": ("world", "export the simulated world's meshes"),
    "recognize": ("recognize", "run the 3D matcher on a model file and a scene file"),
    "record": ("record", "record every message on the bus to an MCAP file"),
    "replay": ("replay", "publish a recording's inputs back on the bus"),
    "up": ("up", "start a deployment layout from compose/"),
    "run": ("run", "replay a recording through a layout in lock-step and record the result"),
    "mcap": ("mcap", "inspect, check and export recordings"),
    "service": ("service", "run one service by name (what the layouts start)"),
    "eval": ("evaluate", "run the paper's experiments and score them"),
    "report": ("report", "write the evaluation report to docs/evaluation"),
    "certs": ("certs", "make a deployment's TLS certificates"),
    "keygen": ("keygen", "make an Ed25519 key pair for sealing recordings"),
    "seal": ("seal", "seal a recording: a signed manifest of every message"),
    "verify": ("verify", "verify a sealed recording against a trusted public key"),
    "audit": ("audit", "audit a recording: provenance, completeness, decisions, errors"),
}


def _version() -> str:
    try:
        return version("passive-atr")
    except PackageNotFoundError:
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every sub-command whose module exists."""
    parser = argparse.ArgumentParser(
        prog="atr", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in COMMANDS.items():
        try:
            module = importlib.import_module(f"cli.{module_name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"cli.{module_name}":
                raise
            continue
        command = sub.add_parser(
            name,
            help=help_text,
            description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(command)
        command.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `atr` console script; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "_run"):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except AtrError as exc:
        print(f"atr {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
