"""The hub every other process connects to: a Zenoh session that listens on a well-known endpoint.

In the `local` layout it is a peer that the other peers meet through (gossip then links them directly);
in the `split` layout it runs on the ground in router mode and the air services connect to it as clients.
No `zenohd` binary is needed: this is a plain Python session.

Example:
    atr service router --mode router --listen tcp/0.0.0.0:7447

"""

from __future__ import annotations

import argparse
import logging

from bus.node import setup_logging
from bus.session import default_config, load_config, open_session
from bus.stopping import StopRequest, stop_on_signals


def main(argv: list[str] | None = None) -> int:
    """Run the hub until SIGTERM/SIGINT."""
    parser = argparse.ArgumentParser(prog="atr service router", description=__doc__)
    parser.add_argument("--mode", choices=["peer", "router"], default="peer")
    parser.add_argument(
        "--listen", action="append", default=[], help="endpoint to listen on (repeatable)"
    )
    parser.add_argument(
        "--zenoh", metavar="JSON5", help="a full Zenoh config file instead of --mode/--listen"
    )
    parser.add_argument("--uav", default="uav1", help="unused; accepted like every service")
    args = parser.parse_args(argv)
    setup_logging("router")
    config = load_config(args.zenoh) if args.zenoh else default_config(args.mode, [], args.listen)
    stop = StopRequest()
    stop_on_signals(stop.set)
    session = open_session(config)
    logging.getLogger("atr").info(
        "listening on %s as %s", config["listen"]["endpoints"], config["mode"]
    )
    stop.wait()
    session.close()
    return 0
