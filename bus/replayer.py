"""The replayer: a recording's inputs back on the bus, in log-time order (docs/recording.md).

Inputs are the messages on `atr/*/camera/image`, `atr/*/imu`, `atr/*/lidar/cloud` and `sim/*/truth`.
Each is published with its recorded bytes (byte-identical payload) and a fresh attachment carrying
the recorded seq (MCAP `sequence`), the recorded stamp (MCAP `publish_time`) and the replayer's own
source id.

Modes (one method each):
- `recorded(rate)`: log-time spacing divided by `rate` (1.0 = as recorded);
- `fast()`: as fast as the bus takes them (publishers block rather than drop);
- `lock_step(answer_key, answer_timeout_s)`: everything up to and including a camera frame is
  published, then the replayer waits for the pipeline's answer to that frame: a message on
  `answer_key` (default `atr/{uav}/detections`) whose `stamp_ns` equals the image's, or an
  ErrorReport on any `atr/{uav}/*/errors` key whose `input_stamp_ns` equals it. A missing answer
  after `answer_timeout_s` is logged, counted and reported on the replayer's errors key, and the
  replay goes on. A service of the vehicle that restarts while a frame waits (killed, restarted by
  its launcher) gets the frame's inputs again: same bytes, same seq and stamp (bus/answers.py).
  See docs/recording.md.

Before the first message the replayer waits until the services named in `wait_for` have published a
Status (their subscribers exist by then), until every publisher has a matching subscriber (or
`match_timeout_s`), and then `settle_s`, so the first messages are not lost.
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh
from mcap.records import Message

from atr.errors import BusError, ConfigError, RecordingError
from bus import codec, keys, mcap_tools
from bus._closing import ClosesOnExit
from bus.answers import DEFAULT_ANSWER_KEY, AnswerWatch
from bus.node import Node
from bus.session import open_session
from bus.stopping import StopRequest

log = logging.getLogger("atr.replayer")

INPUT_TOPIC = re.compile(
    r"^(atr/[^/]+/(" + "|".join(re.escape(k) for k in keys.INPUT_KEYS) + r")|sim/[^/]+/truth)$"
)
IMAGE_TOPIC = re.compile(r"^atr/([^/]+)/camera/image$")


def is_input_topic(topic: str) -> bool:
    """True for the keys a replay publishes (camera images, IMU batches, LIDAR clouds, simulator
    truth).
    """
    return INPUT_TOPIC.match(topic) is not None


@dataclass
class ReplayStats:
    """What a replay did."""

    published: int = 0
    bytes: int = 0
    frames: int = 0
    answered: int = 0
    timeouts: int = 0
    resent: int = 0  # frames sent again after a service restarted while they were in flight
    wall_s: float = 0.0
    by_topic: dict[str, int] = field(default_factory=dict)


class Replayer(ClosesOnExit):
    """Publishes the inputs of one recording; usable in-process (`atr run`) or from `atr replay`.

    Args:
        path: the MCAP recording (its first segment; continued segments and a cut one are read
            as far as they go).
        session: an open Zenoh session to publish on (not closed here); None opens one from
            `zenoh_config`.
        zenoh_config: config dict or JSON5 path, used when `session` is None.
        uav: replay only this vehicle's inputs (None: every vehicle in the recording).
        wait_for: services (e.g. "sfm") whose `running` Status must be seen before the first message.
        ready_timeout_s: how long to wait for those services, seconds.
        match_timeout_s: how long to wait for each publisher to have a matching subscriber, seconds.
        settle_s: extra pause before the first message, seconds.
        service: name of the replayer's own status/errors keys (`atr/{status_uav}/{service}/...`).
        status_uav: vehicle id of those keys.

    Raises:
        RecordingError: the file is missing, not MCAP, or holds no input.

    """

    def __init__(
        self,
        path: str | Path,
        session: zenoh.Session | None = None,
        *,
        zenoh_config: dict[str, Any] | str | None = None,
        uav: str | None = None,
        wait_for: tuple[str, ...] | list[str] = (),
        ready_timeout_s: float = 30.0,
        match_timeout_s: float = 5.0,
        settle_s: float = 0.3,
        service: str = "replayer",
        status_uav: str = "uav1",
    ) -> None:
        self.path = Path(path)
        self.topics = self._input_topics(uav)
        self._owns_session = session is None
        self.session = session if session is not None else open_session(zenoh_config)
        self.node = Node(service, status_uav, session=self.session)
        self.source_id = self.node.source_id
        self.stats = ReplayStats()
        self._stop = StopRequest()
        self._wait_for = tuple(wait_for)
        self._ready_timeout_s = ready_timeout_s
        self._match_timeout_s = match_timeout_s
        self._settle_s = settle_s
        self._watch: AnswerWatch | None = None
        self._publishers = {
            topic: self.session.declare_publisher(
                topic, congestion_control=zenoh.CongestionControl.BLOCK
            )
            for topic in self.topics
        }

    # Public interface --------------------------------------------------------------------------

    def recorded(
        self, rate: float = 1.0, on_publish: Callable[[str, Message], None] | None = None
    ) -> ReplayStats:
        """Publish with the recording's log-time spacing divided by `rate` (2.0 = twice as fast);
        `on_publish` sees each message after it is sent.

        Raises:
            ConfigError: `rate` is not > 0.

        """
        if not rate > 0:
            raise ConfigError(f"replay rate {rate} must be > 0")
        self._get_ready()
        start_wall = time.monotonic()
        first_log: int | None = None
        for topic, message in self._messages():
            first_log = message.log_time if first_log is None else first_log
            delay = start_wall + (message.log_time - first_log) / 1e9 / rate - time.monotonic()
            if delay > 0 and self._stop.wait(delay):
                break
            self._publish(topic, message)
            if on_publish is not None:
                on_publish(topic, message)
        return self._finish(start_wall)

    def fast(self) -> ReplayStats:
        """Publish every input as fast as the bus takes it."""
        self._get_ready()
        start_wall = time.monotonic()
        for topic, message in self._messages():
            self._publish(topic, message)
        return self._finish(start_wall)

    def lock_step(
        self, answer_key: str = DEFAULT_ANSWER_KEY, answer_timeout_s: float = 60.0
    ) -> ReplayStats:
        """Publish up to and including each camera frame, then wait for the pipeline's answer to
        that frame.

        Args:
            answer_key: key of the answers; `{uav}` is replaced by the frame's vehicle id.
            answer_timeout_s: how long to wait for one answer before warning and going on, seconds.

        Raises:
            ConfigError: `answer_timeout_s` is not > 0.

        """
        if not answer_timeout_s > 0:
            raise ConfigError(f"answer timeout {answer_timeout_s} s must be > 0")
        self._watch = AnswerWatch(self.session, self.node.service, answer_key)
        try:
            self._get_ready()
            start_wall = time.monotonic()
            frame: list[tuple[str, Message]] = []  # the inputs of the frame in flight
            since = self._watch.mark()
            for topic, message in self._messages():
                self._publish(topic, message)
                frame.append((topic, message))
                image = IMAGE_TOPIC.match(topic)
                if image is not None:
                    self._await_answer(
                        image.group(1), message, answer_key, answer_timeout_s, frame, since
                    )
                    frame, since = [], self._watch.mark()
            return self._finish(start_wall)
        finally:
            self._watch.close()
            self._watch = None

    def paced(
        self,
        rate: float = 1.0,
        answer_key: str = DEFAULT_ANSWER_KEY,
        answer_timeout_s: float = 60.0,
    ) -> ReplayStats:
        """Publish at the recording's pace (`recorded`), never waiting on an answer, then wait up to
        `answer_timeout_s` after the last input for every frame's answer: the pipeline as it runs in
        flight, where the camera does not wait for the matcher.

        Raises:
            ConfigError: `rate` or `answer_timeout_s` is not > 0.

        """
        if not answer_timeout_s > 0:
            raise ConfigError(f"answer timeout {answer_timeout_s} s must be > 0")
        self._watch = AnswerWatch(self.session, self.node.service, answer_key)
        frames: list[tuple[str, Message]] = []

        def note_frame(topic: str, message: Message) -> None:
            image = IMAGE_TOPIC.match(topic)
            if image is not None:
                frames.append((image.group(1), message))

        try:
            stats = self.recorded(rate, on_publish=note_frame)
            first_input_wall = time.monotonic() - stats.wall_s
            deadline = time.monotonic() + answer_timeout_s
            for uav, image in frames:
                stats.frames += 1
                left = max(0.0, deadline - time.monotonic())
                if self._watch.wait(uav, image.publish_time, left, self._stop):
                    stats.answered += 1
                elif not self._stop.is_set():
                    stats.timeouts += 1
            return self._finish(first_input_wall)
        finally:
            self._watch.close()
            self._watch = None

    def run(self, mode: str = "lock-step", **kwargs: Any) -> ReplayStats:
        """Dispatch to `recorded`, `fast`, `lock_step` or `paced` by name ("recorded", "fast",
        "lock-step", "paced").

        Raises:
            ConfigError: unknown mode.

        """
        methods = {
            "recorded": self.recorded,
            "fast": self.fast,
            "lock-step": self.lock_step,
            "paced": self.paced,
        }
        if mode not in methods:
            raise ConfigError(f"replay mode {mode!r} must be one of {sorted(methods)}")
        return methods[mode](**kwargs)

    def stop(self) -> None:
        """Ask a running replay to end after the message in hand. Takes no lock: signal handlers
        call it.
        """
        self._stop.set()

    def close(self, linger_s: float = 0.3) -> None:
        """Let the last publications leave (`linger_s`), then undeclare and close what this replayer
        opened.
        """
        if linger_s > 0:
            time.sleep(linger_s)
        for pub in self._publishers.values():
            pub.undeclare()
        self._publishers = {}
        self.node.close()
        if self._owns_session:
            self.session.close()

    # Internals ---------------------------------------------------------------------------------

    def _input_topics(self, uav: str | None) -> list[str]:
        if not self.path.is_file():
            raise RecordingError(f"recording {self.path} does not exist")
        # every segment's channels (flight.mcap, flight.1.mcap, ...); a cut first segment is read
        # as far as it goes
        topics = [
            t
            for t in mcap_tools.topics(self.path)
            if is_input_topic(t) and (uav is None or t.split("/")[1] == uav)
        ]
        if not topics:
            which = f" for {uav}" if uav else ""
            raise RecordingError(
                f"{self.path} holds no input{which} (camera/image, imu, lidar/cloud, truth)"
            )
        return topics

    def _messages(self) -> Iterator[tuple[str, Message]]:
        # All segments of the recording (flight.mcap, flight.1.mcap, ...) as one; a chunk that
        # cannot be read raises a RecordingError naming the file and the chunk's offset.
        for topic, message in mcap_tools.iter_messages(self.path, topics=self.topics):
            if self._stop.is_set():
                return
            yield topic, message

    def _publish(self, topic: str, message: Message) -> None:
        attachment = codec.encode_attachment(message.sequence, message.publish_time, self.source_id)
        self._publishers[topic].put(message.data, attachment=attachment)
        s = self.stats
        s.published += 1
        s.bytes += len(message.data)
        s.by_topic[topic] = s.by_topic.get(topic, 0) + 1
        self.node.counters.published += 1

    def _get_ready(self) -> None:
        if self._wait_for:
            self._wait_for_services()
        deadline = time.monotonic() + self._match_timeout_s
        for topic, pub in self._publishers.items():
            while not (pub.matching_status or self._stop.is_set() or time.monotonic() > deadline):
                time.sleep(0.01)
            if not pub.matching_status:
                log.warning(
                    "no subscriber for %s after %.1f s; publishing anyway",
                    topic,
                    self._match_timeout_s,
                )
        self._stop.wait(self._settle_s)

    def _wait_for_services(self) -> None:
        from bus.launcher import wait_until_ready

        wait_until_ready(self.session, "*", list(self._wait_for), self._ready_timeout_s)

    def _await_answer(
        self,
        uav: str,
        image: Message,
        answer_key: str,
        timeout_s: float,
        frame: list[tuple[str, Message]],
        since: int,
    ) -> None:
        stamp = image.publish_time

        def send_again() -> None:
            # a service restarted while this frame was in flight: it may have missed its inputs
            log.warning("a service restarted: sending the frame of stamp %d ns again", stamp)
            self.stats.resent += 1
            for topic, message in frame:
                if topic.split("/")[1] == uav:
                    self._publish(topic, message)

        self.stats.frames += 1
        answered = self._watch.wait(uav, stamp, timeout_s, self._stop, send_again, since)
        if self._stop.is_set():
            return
        if answered:
            self.stats.answered += 1
            return
        self.stats.timeouts += 1
        key = answer_key.replace("{uav}", uav)
        self.node.report_error(
            keys.image(uav),
            BusError(
                f"no answer on {key} (or an ErrorReport) to the frame of stamp {stamp} ns "
                f"within {timeout_s} s"
            ),
            input_seq=image.sequence,
            input_stamp_ns=stamp,
            input_source=self.source_id,
        )

    def _finish(self, start_wall: float) -> ReplayStats:
        self.stats.wall_s = time.monotonic() - start_wall
        return self.stats
