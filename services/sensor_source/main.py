"""sensor_source: the simulated UAV's sensors on the bus — camera images, IMU batches, LIDAR scans, truth.

It flies one scenario run of Table II in the simulated world (atr/sim) and publishes, per frame, in this
order: the ImuBatch (samples since the previous frame; the first carries the initial navigation state, as a
GNSS/INS alignment before take-off would), the LIDAR cloud (with --lidar), the truth, and the Image.
`atr simulate` writes the same messages straight into a recording.

Pacing: `--pace realtime` (the frame interval of the flight), `--pace fast` (as fast as it renders), or
`--pace lock-step` (the next frame only after the pipeline answered the last: a Detections or an ErrorReport
stamped with the frame's stamp_ns; nothing is ever dropped). A service that restarts while a frame waits gets
the frame's messages again (the same bytes, seq and stamp).

Example:
    atr service sensor_source --scenario 1 --run 3 --frames 20 --pace lock-step

"""

from __future__ import annotations

import logging
import time

from bus import keys
from bus.answers import AnswerWatch
from bus.flight_messages import add_flight_arguments, flight_frame_messages, flight_frames
from bus.service import effective_config, service_arguments, start_node

log = logging.getLogger("atr")


def main(argv: list[str] | None = None) -> int:
    """Fly the run, then exit."""
    parser = service_arguments("sensor_source", __doc__)
    add_flight_arguments(parser)
    parser.add_argument("--pace", choices=["realtime", "fast", "lock-step"], default="lock-step")
    parser.add_argument(
        "--answer-timeout", type=float, default=600.0, help="lock-step wait per frame, s"
    )
    args = parser.parse_args(argv)
    config = effective_config(args)
    frames = flight_frames(config, args)
    with start_node("sensor_source", args, inputs=[]) as node:
        watch = AnswerWatch(node.session, node.service)
        node.ready()
        time.sleep(1.0)  # let gossip connect every peer before the first frame
        last_stamp: int | None = None
        for frame, messages in flight_frame_messages(config, args, frames):
            if node.stopping:
                break
            if args.pace == "realtime" and last_stamp is not None:
                time.sleep(max(0.0, (frame.stamp_ns - last_stamp) * 1e-9))
            since, sent = watch.mark(), []
            for key, message in messages:
                node.publish(key, message)
                sent.append(key)

            def send_again(keys_sent: list[str] = sent, stamp: int = frame.stamp_ns) -> None:
                # a service restarted while the frame was in flight: the same messages again
                log.warning("a service restarted: sending the frame of stamp %d ns again", stamp)
                for key in keys_sent:
                    node.republish(key, stamp)

            last_stamp = frame.stamp_ns
            if args.pace == "lock-step" and not watch.wait(
                args.uav, frame.stamp_ns, args.answer_timeout, on_restart=send_again, since=since
            ):
                node.report_error(
                    keys.detections(args.uav),
                    TimeoutError(f"no answer to frame {frame.seq} within {args.answer_timeout} s"),
                    frame.seq,
                    frame.stamp_ns,
                )
            log.info("frame %d published", frame.seq)
    return 0
