"""Seal a recording: a signed manifest (`FILE.seal`) of every message and definition it holds.

Reads the file once, hashes every record (topic, log time, sequence, payload) into a Merkle tree and
signs its root with an Ed25519 key from `atr keygen`. `atr verify FILE --pub KEY.pub` later names every
message changed, added, removed or moved since (docs/recording.md, "Chain of custody").

Examples:
    atr seal runs/flight.mcap --key keys/recorder.key          # writes runs/flight.mcap.seal

"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr seal`."""
    parser.add_argument("file", help="the MCAP recording to seal")
    parser.add_argument("--key", required=True, help="Ed25519 private key (from `atr keygen`)")
    parser.add_argument("--out", help="where to write the manifest (default: FILE.seal)")


def run(args: argparse.Namespace) -> int:
    """Seal the file; returns 0, or raises an AtrError that `atr` prints."""
    from bus.seal import load_private_key, seal, seal_path

    manifest = seal(args.file, load_private_key(args.key), args.out)
    out = args.out or seal_path(args.file)
    print(f"sealed {args.file}: {manifest['messages']} messages, {manifest['records']} records")
    print(f"root {manifest['root']}, key {manifest['key']}")
    print(f"manifest: {out}")
    return 0
