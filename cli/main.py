"""The `atr` command: a thin shell that maps sub-commands onto the modules that implement them.

Each sub-command lives in `cli/<module>.py` with `add_arguments(parser)` and `run(args) -> int`.
Heavy imports stay inside `run`, and only the chosen sub-command's module is imported, so `atr --help` is
instant and a command pays only for its own imports.

Examples:
    atr demo                                   # simulated flight end to end over the bus
    atr simulate --scenario 1 --run 3 --frames 20 --out flight.mcap
    atr run flight.mcap --out result.mcap      # replay in lock-step through the service graph

"""

from __future__ import annotations

import os

# What `./dev` sets, for an `atr` installed with pip too; before numpy and numba are imported, and never over
# a user's own setting. Debian's TBB is too old for numba (a warning on every run): numba's OpenMP layer instead.
# One BLAS thread: the matcher's small products ran up to 10x slower with BLAS threads fighting the services'.
os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import sys  # noqa: E402

from atr.errors import AtrError  # noqa: E402

# name -> one-line help of every sub-command; its module is cli/<name>.py unless _MODULE_OF names another
COMMANDS: dict[str, str] = {
    "demo": "simulate a short flight and run the whole service graph over Zenoh",
    "simulate": "simulate a scenario run straight into an MCAP recording",
    "world": "export the simulated world's meshes",
    "recognize": "run the 3D matcher on a model file and a scene file",
    "record": "record every message on the bus to an MCAP file",
    "replay": "publish a recording's inputs back on the bus",
    "up": "start a deployment layout from compose/",
    "run": "replay a recording through a layout in lock-step and record the result",
    "mcap": "inspect, check and export recordings",
    "diff": "compare the data messages of two recordings (exit 0 same, 1 differ, 2 error)",
    "regress": "replay a corpus of recordings and diff each against its baseline",
    "service": "run one service by name (what the layouts start)",
    "eval": "run the paper's experiments and score them",
    "report": "write the evaluation report to docs/evaluation",
    "certs": "make a deployment's TLS certificates",
    "keygen": "make an Ed25519 key pair for sealing recordings",
    "seal": "seal a recording: a signed manifest of every message",
    "verify": "verify a sealed recording against a trusted public key",
    "audit": "audit a recording: provenance, completeness, decisions, errors",
}
_MODULE_OF: dict[str, str] = {"eval": "evaluate"}  # `eval` is a Python builtin


class _VersionAction(argparse.Action):
    """`--version`, reading the installed package's metadata only when asked (it costs start-up time)."""

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> None:
        from importlib.metadata import PackageNotFoundError, version

        try:
            found = version("passive-atr")
        except PackageNotFoundError:
            found = "unknown"
        parser.exit(message=f"{parser.prog} {found}\n")


def _chosen(argv: list[str]) -> str | None:
    """The sub-command named on the command line (the first word that is not an option), if any."""
    return next((word for word in argv if not word.startswith("-")), None)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Build the argument parser of every sub-command.

    Args:
        only: the sub-command about to run: only its module is imported and given its arguments (the
            others are listed with their one-line help), so a command never pays for another's imports;
            "" imports none (top-level help). None imports and builds every sub-command.

    """
    parser = argparse.ArgumentParser(
        prog="atr", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action=_VersionAction, nargs=0, help="print the version")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        module_name = _MODULE_OF.get(name, name)
        if only is not None and name != only:
            sub.add_parser(name, help=help_text)
            continue
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
    argv = sys.argv[1:] if argv is None else list(argv)
    chosen = _chosen(argv)
    parser = build_parser(chosen if chosen in COMMANDS else "")
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
