"""Verify a sealed recording with the public key you trust: exit 0 when it holds exactly what was
sealed, 1 naming each message changed, added, removed or moved (topic, log time, sequence), 2 when the
recording, the seal or the key cannot be read.

The key is the one you were given by whoever sealed the file, never one read from the file or the seal.

Examples:
    atr verify runs/flight.mcap --pub keys/recorder.pub
    atr verify copy.mcap --pub keys/recorder.pub --seal runs/flight.mcap.seal
    atr verify air.mcap --pub deploy/air-uav1-recorder.pub --json air.mcap.receipt.json

"""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr verify`."""
    parser.add_argument("file", help="the MCAP recording to verify")
    parser.add_argument("--pub", required=True, help="the trusted Ed25519 public key (.pub)")
    parser.add_argument("--seal", help="the manifest (default: FILE.seal)")
    parser.add_argument("--max-lines", type=int, default=50, help="problems listed at most")
    parser.add_argument(
        "--json",
        metavar="OUT",
        help="write the verdict (the ground's receipt: file hash, key, time, every problem) as JSON",
    )


def run(args: argparse.Namespace) -> int:
    """Verify; print the verdict; return 0 intact, 1 altered, 2 unreadable."""
    from atr.errors import AtrError
    from bus.seal import load_public_key, verify, write_receipt

    try:
        public_key = load_public_key(args.pub)
        verdict = verify(args.file, public_key, args.seal)
        if args.json:
            write_receipt(args.json, args.file, public_key, verdict)
    except AtrError as exc:
        print(f"atr verify: {exc}", file=sys.stderr)
        return 2
    if verdict.intact:
        print(f"intact: {args.file} holds the {verdict.sealed_messages} sealed messages, unchanged")
        return 0
    lines = verdict.lines()
    print(f"NOT intact: {args.file}: {len(lines)} problem(s)")
    for line in lines[: args.max_lines]:
        print(f"  {line}")
    if len(lines) > args.max_lines:
        print(f"  ... and {len(lines) - args.max_lines} more")
    return 1
