"""Bus helpers the deployment tests run inside a host's namespace (the test process itself is outside).

python _ns_helper.py wait-ready --zenoh CONFIG --services a,b,c --timeout 300
    exits 0 once every service published a `running` Status, 1 on timeout (names the missing ones)
python _ns_helper.py watch --zenoh CONFIG
    prints one JSON line per image, truth, detections, errors or status message it sees:
    {"t_ns": receive wall time, "key": ..., "stamp_ns": ..., "bytes": payload size, ...} until SIGTERM
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bus import codec  # noqa: E402
from bus.launcher import wait_until_ready  # noqa: E402
from bus.session import open_session  # noqa: E402


def wait_ready(args: argparse.Namespace) -> int:
    session = open_session(args.zenoh)
    try:
        wait_until_ready(session, args.uav, args.services.split(","), args.timeout)
    except Exception as exc:  # reported to the test through the exit code and stderr
        print(exc, file=sys.stderr)
        return 1
    finally:
        session.close()
    return 0


def watch(args: argparse.Namespace) -> int:
    session = open_session(args.zenoh)
    lock = threading.Lock()

    def on_sample(sample: object) -> None:
        t_ns = time.time_ns()
        payload = sample.payload.to_bytes()
        key = str(sample.key_expr)
        event = {"t_ns": t_ns, "key": key, "bytes": len(payload)}
        try:
            message = codec.unpack(payload)
        except Exception:
            message = {}
        for field in ("stamp_ns", "seq", "input_stamp_ns", "reason", "state", "service"):
            if field in message:
                event[field] = message[field]
        if key.endswith("/status"):
            event["counters"] = message.get("counters")
        with lock:
            print(json.dumps(event), flush=True)

    uav = args.uav
    subs = [
        session.declare_subscriber(k, on_sample)
        for k in (
            f"atr/{uav}/camera/image",
            f"sim/{uav}/truth",
            f"atr/{uav}/detections",
            f"atr/{uav}/*/errors",
            f"atr/{uav}/*/status",
            f"atr/{uav}/sfm/cloud",
        )
    ]
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    print(json.dumps({"ready": True}), flush=True)
    stop.wait(args.timeout)
    for sub in subs:
        sub.undeclare()
    session.close()
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("command", choices=["wait-ready", "watch"])
    parser.add_argument("--zenoh", required=True)
    parser.add_argument("--uav", default="uav1")
    parser.add_argument("--services", default="")
    parser.add_argument("--timeout", type=float, default=600.0)
    args = parser.parse_args()
    return wait_ready(args) if args.command == "wait-ready" else watch(args)


if __name__ == "__main__":
    raise SystemExit(main())
