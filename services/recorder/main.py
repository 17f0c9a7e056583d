"""The recorder service: everything on the bus into one MCAP file (see bus/recorder.py,
docs/recording.md).

Started by every layout; stops and closes its file on SIGTERM/SIGINT. Settings come from the command
line or from the environment (ATR_RECORDER_OUT, ATR_UAV); see service.yml.
"""

from __future__ import annotations

import os
import sys
import time

from atr.errors import AtrError
from bus.service import service_arguments


def main(argv: list[str] | None = None) -> int:
    """Run the recorder until stopped; returns the process exit code."""
    # --uav, --zenoh, --config and --set as every service takes them; the pipeline's --config and
    # --set are only recorded here (provenance), never applied
    parser = service_arguments("recorder", __doc__)
    parser.set_defaults(uav=os.environ.get("ATR_UAV", "uav1"))
    parser.add_argument(
        "--out",
        default=os.environ.get("ATR_RECORDER_OUT")
        or time.strftime("runs/recording-%Y%m%d-%H%M%S.mcap"),
        help="MCAP file to write (default $ATR_RECORDER_OUT or runs/recording-<time>.mcap); "
        "when it exists (a restart), the next segment OUT.1.mcap, ... is written",
    )
    parser.add_argument(
        "--flush-interval",
        type=float,
        default=float(os.environ.get("ATR_RECORDER_FLUSH_S", "1.0")),
        help="max age of an unwritten chunk, s",
    )
    # What the launcher knows of the run, for the recording's provenance record.
    parser.add_argument("--layout", default="", help="the layout this recorder runs in")
    parser.add_argument(
        "--input", metavar="MCAP", help="the recording a replay publishes (its SHA-256 is recorded)"
    )
    parser.add_argument(
        "--seal-key",
        metavar="KEY",
        help="Ed25519 private key (`atr keygen`, `atr certs`): seal each file when it closes",
    )
    args = parser.parse_args(argv)

    from bus.node import setup_logging
    from bus.provenance import RunContext
    from bus.recorder import RecorderConfig, run_recorder

    setup_logging("recorder")
    try:
        run_recorder(
            args.out,
            uav=args.uav,
            zenoh_config=args.zenoh,
            config=RecorderConfig(flush_interval_s=args.flush_interval),
            seal_key=args.seal_key,
            context=RunContext(
                uav=args.uav,
                layout=args.layout,
                overrides=tuple(args.overrides),
                config_file=args.config,
                input_recording=args.input,
            ),
        )
    except AtrError as exc:
        print(f"recorder: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
