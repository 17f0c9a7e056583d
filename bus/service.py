"""What every service's `main()` shares: its command line, its config, and its Node.

A service's main.py stays a thin loop:

    def main(argv=None) -> int:
        args = service_arguments("sfm", __doc__).parse_args(argv)
        with start_node("sfm", args, inputs=[...]) as node:
            ...
"""

from __future__ import annotations

import argparse
import logging
from typing import TYPE_CHECKING, Any

from bus.node import Node, setup_logging

if TYPE_CHECKING:
    from atr.config import AtrConfig


def service_arguments(name: str, description: str | None) -> argparse.ArgumentParser:
    """The arguments every service takes; a service adds its own on the returned parser."""
    parser = argparse.ArgumentParser(
        prog=f"atr service {name}",
        description=description,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--uav", default="uav1", help="vehicle id in the key expressions (default uav1)"
    )
    parser.add_argument(
        "--zenoh",
        metavar="JSON5",
        help="Zenoh config file (default: ATR_ZENOH_CONFIG, or peer on loopback)",
    )
    parser.add_argument(
        "--config", metavar="YAML", help="config file of nested groups (see atr/config.py)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="GROUP.FIELD=VALUE",
        help="override one config field, e.g. --set sfm.matcher=surf (repeatable)",
    )
    return parser


def effective_config(args: argparse.Namespace) -> AtrConfig:
    """The config a service runs with: defaults, then --config, then --set."""
    from atr.config import load_config  # the algorithms' configs import Open3D

    return load_config(args.config, args.overrides)


def start_node(name: str, args: argparse.Namespace, inputs: list[str], **kwargs: Any) -> Node:
    """Set up logging and open the service's Node with its inputs subscribed."""
    setup_logging(name)
    logging.getLogger("atr").info("starting (uav %s, inputs %s)", args.uav, inputs)
    return Node(name, args.uav, inputs, zenoh_config=args.zenoh, **kwargs)
