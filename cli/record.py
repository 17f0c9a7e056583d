"""Record every message on the bus (`atr/**`, `sim/**`) into one MCAP file until Ctrl-C or SIGTERM.

The file follows docs/recording.md (msgpack messages, JSON Schema channels, zstd chunks, log time =
receive time); see docs/recording.md. A chunk is written at least every `--flush-interval` seconds,
so a crash loses at most that much (`atr mcap recover` repairs a file cut short). An existing file is
never overwritten: recording again to the same `--out` writes the next segment (`flight.1.mcap`, ...), and
the `atr mcap` tools read the segments as one recording.

Examples:
    atr record --out runs/flight.mcap            # default Zenoh session (ATR_ZENOH_* env)
    atr record --out runs/ground.mcap --zenoh compose/zenoh/local.json5
    atr record --out runs/uav2.mcap --uav uav2 --flush-interval 0.5

"""

from __future__ import annotations

import argparse

from bus.service import add_zenoh_argument
from cli._args import add_repeatable


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr record`."""
    parser.add_argument(
        "--out",
        required=True,
        help="MCAP file to write (folders are created); never overwritten: when it exists, the "
        "next segment OUT.1.mcap, OUT.2.mcap, ... is written",
    )
    add_zenoh_argument(parser)
    parser.add_argument(
        "--uav", default="uav1", help="vehicle id of the recorder's own status/errors keys"
    )
    parser.add_argument(
        "--service", default="recorder", help="service name of its status/errors keys"
    )
    add_repeatable(
        parser,
        "--key",
        "key expression to record",
        "atr/** and sim/**",
        dest="keys",
        metavar="KEYEXPR",
    )
    parser.add_argument("--chunk-size", type=int, default=8 * 1024 * 1024, help="chunk size, bytes")
    parser.add_argument(
        "--flush-interval", type=float, default=1.0, help="max age of an unwritten chunk, s"
    )
    parser.add_argument(
        "--zstd-level", type=int, default=1, help="zstd level of chunks (default 1)"
    )


def run(args: argparse.Namespace) -> int:
    """Record until stopped; returns 0, or 1 when the file could not be written."""
    from bus.node import setup_logging
    from bus.recorder import DEFAULT_KEY_EXPRS, RecorderConfig, run_recorder

    setup_logging(args.service)
    config = RecorderConfig(
        key_exprs=tuple(args.keys) if args.keys else DEFAULT_KEY_EXPRS,
        chunk_size_bytes=args.chunk_size,
        flush_interval_s=args.flush_interval,
        zstd_level=args.zstd_level,
    )
    run_recorder(
        args.out, uav=args.uav, zenoh_config=args.zenoh, config=config, service=args.service
    )
    return 0
