"""What every service's `main()` shares: its command line, its config, and its Node.

A service's main.py stays a thin loop:

    def main(argv=None) -> int:
        args = service_arguments("sfm", __doc__, keeps="journal").parse_args(argv)
        with start_node("sfm", args, inputs=[...]) as node:
            ...
"""

from __future__ import annotations

import argparse
import logging
from typing import TYPE_CHECKING, Any

if (
    TYPE_CHECKING
):  # bus.node (numpy, the codec) only when a Node opens: the CLI's parsers use this module
    from atr.config import AtrConfig
    from bus.node import Node


def add_zenoh_argument(parser: argparse.ArgumentParser) -> None:
    """`--zenoh`, the Zenoh config of a process on the bus (bus/session.py reads it)."""
    parser.add_argument(
        "--zenoh",
        metavar="JSON5",
        help="Zenoh config file (default: ATR_ZENOH_CONFIG, else a peer on ATR_ZENOH_CONNECT or "
        "loopback)",
    )


class _Preset(argparse.Action):
    """`--preset NAME` as the override `preset=NAME`, in its place among the --set (a later --set
    refines it); load_config checks the name, so the parsers need not import the config tree.
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        overrides = list(getattr(namespace, self.dest, None) or [])
        setattr(namespace, self.dest, [*overrides, f"preset={values}"])


def add_overrides_argument(
    parser: argparse.ArgumentParser,
    help_text: str = "override one config field, e.g. --set sfm.matcher=surf (repeatable)",
) -> None:
    """`--set GROUP.FIELD=VALUE` (repeatable) and `--preset NAME` into `args.overrides`, in the order
    given, as atr/config.py's load_config reads them.
    """
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="GROUP.FIELD=VALUE",
        help=help_text,
    )
    parser.add_argument(
        "--preset",
        dest="overrides",
        action=_Preset,
        metavar="NAME",
        help="a named set of overrides (atr/config.py PRESETS), where it stands among the --set: "
        "'paper' is the paper's sparse GFTT/KLT SfM, 'dense' the default (dense SfM, SGM)",
    )


def service_arguments(
    name: str, description: str | None, keeps: str | None = None
) -> argparse.ArgumentParser:
    """The arguments every service takes; a service adds its own on the returned parser.

    Args:
        name: the service's name.
        description: its help text (its main.py's docstring).
        keeps: what a service that survives a restart keeps on disk ("journal", "checkpoint"): adds
            `--state-dir`, which `start_node` opens the Node with.

    """
    parser = argparse.ArgumentParser(
        prog=f"atr service {name}",
        description=description,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--uav", default="uav1", help="vehicle id in the key expressions (default uav1)"
    )
    add_zenoh_argument(parser)
    parser.add_argument(
        "--config", metavar="YAML", help="config file of nested groups (see atr/config.py)"
    )
    add_overrides_argument(parser)
    if keeps is not None:
        parser.add_argument(
            "--state-dir", help=f"{keeps} folder (default: ATR_STATE_DIR or one per launcher)"
        )
    return parser


def effective_config(args: argparse.Namespace) -> AtrConfig:
    """The config a service runs with: defaults, then --config, then --set."""
    from atr.config import load_config  # the algorithms' configs import Open3D

    return load_config(args.config, args.overrides)


def start_node(name: str, args: argparse.Namespace, inputs: list[str], **kwargs: Any) -> Node:
    """Set up logging and open the service's Node with its inputs subscribed (and its state folder,
    when it takes `--state-dir`).
    """
    from bus.node import Node, default_state_dir, setup_logging

    if "state_dir" in args:
        kwargs.setdefault("state_dir", args.state_dir or default_state_dir())
    setup_logging(name)
    logging.getLogger("atr").info("starting (uav %s, inputs %s)", args.uav, inputs)
    return Node(name, args.uav, inputs, zenoh_config=args.zenoh, **kwargs)
