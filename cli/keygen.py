"""Make an Ed25519 key pair for sealing recordings: `NAME.key` (private, owner-only) and `NAME.pub`.

The private key stays with whoever seals (the air recorder's host); the public key goes to whoever
verifies, who pins it: `atr verify` never trusts a key found in the file it checks (docs/recording.md,
"Chain of custody").

Examples:
    atr keygen --out keys/                       # keys/recorder.key, keys/recorder.pub
    atr keygen --out keys/ --name uav1-recorder

"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr keygen`."""
    parser.add_argument("--out", required=True, help="folder to write the key pair to")
    parser.add_argument("--name", default="recorder", help="file name stem (default: recorder)")


def run(args: argparse.Namespace) -> int:
    """Write the key pair; refuse to overwrite an existing one."""
    from bus.seal import fingerprint, generate_keys, load_public_key

    private_path, public_path = generate_keys(args.out, args.name)
    print(f"private key: {private_path} (keep it secret; it signs recordings)")
    print(f"public key:  {public_path} (give it to verifiers)")
    print(f"fingerprint: {fingerprint(load_public_key(public_path))}")
    return 0
