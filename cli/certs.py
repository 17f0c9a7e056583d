"""Make a split deployment's credentials: a CA, mutual-TLS certificates, and the Zenoh configs that use them.

The folder it writes is what `atr up split --var deploy=DIR` reads (docs/deployment.md). Copy to the aircraft
only what it needs: ca.pem, air-<uav>.pem, air-<uav>.key and zenoh/split-air*.json5 (never ca.key).

Examples:
    atr certs --out deploy --ground 10.0.0.1
    atr certs --out deploy --ground ground.example.org --uav uav2 --matcher-on-air

"""

from __future__ import annotations

import argparse
from pathlib import Path

from cli._args import add_repeatable, forwarded

# the options that are make_deployment's keywords of the same names: all but --out
_DEPLOYMENT_OPTIONS = (
    "ground",
    "uav",
    "port",
    "air_port",
    "matcher_on_air",
    "images_to_ground",
    "extra_hosts",
    "days",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr certs`."""
    parser.add_argument("--out", type=Path, required=True, help="folder to write (created)")
    parser.add_argument(
        "--ground", required=True, help="the ground router's address as the air reaches it"
    )
    parser.add_argument(
        "--uav", default="uav1", help="vehicle id the air certificate may publish for"
    )
    parser.add_argument("--port", type=int, default=7447, help="the ground router's TLS port")
    parser.add_argument("--air-port", type=int, default=7448, help="the air router's loopback port")
    parser.add_argument(
        "--matcher-on-air",
        action="store_true",
        help="the layout runs atr_matcher on the air: the air may publish detections",
    )
    parser.add_argument(
        "--images-to-ground",
        action="store_true",
        help="let camera images cross the radio link (off: they stay on the air)",
    )
    add_repeatable(
        parser, "--host", "another name or address of the ground router", dest="extra_hosts"
    )
    parser.add_argument("--days", type=int, default=825, help="certificate lifetime, days")


def run(args: argparse.Namespace) -> int:
    """Write the deployment folder and list what it holds."""
    from atr.errors import ConfigError
    from bus.certs import make_deployment

    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out} is a file; expected a folder to write (created)")
    deployment = make_deployment(args.out, **forwarded(args, *_DEPLOYMENT_OPTIONS))
    for path in sorted(deployment.root.rglob("*")):
        if path.is_file():
            print(path.relative_to(deployment.root))
    print(
        f"start with: atr up split --host ground --var deploy={args.out}  (and --host air on the aircraft)"
    )
    return 0
