"""Compare the data messages of two recordings: the engine of `atr diff` and `atr regress`.

Messages are aligned per topic by frame: the MCAP `publish_time` (the message's `stamp_ns`) and, for
several messages of one topic at one stamp, their order. An aligned pair with equal bytes is the same
without decoding (the fast path); otherwise both are decoded with `bus.codec.unpack` and compared field by
field (`atr.regression.compare`) under the tolerances in force. Status and Timing topics (wall clock) and
the `input_source` of ErrorReports (a process id) are ignored by default (docs/regression.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from atr.errors import AtrError, RecordingError
from atr.regression.compare import FieldDifference, compare_messages, short
from atr.regression.report import (
    DIFFERS,
    IDENTICAL,
    ONLY_BASE,
    ONLY_NEW,
    WITHIN_TOLERANCE,
    DiffReport,
    TopicDiff,
    worst,
)
from atr.regression.tolerances import Tolerances
from bus import codec
from bus.mcap_tools import segments


@dataclass
class _Topic:
    message_type: str
    encoding: str
    schema: bytes
    # (stamp_ns, payload) in log-time order
    messages: list[tuple[int, bytes]] = field(default_factory=list)


def _read(path: str | Path) -> dict[str, _Topic]:
    """Every message of the recording `path` by topic (payloads not decoded): all its segments,
    when a restarted recorder continued it (`flight.1.mcap`, ...).

    Raises:
        RecordingError: the file is missing or not a readable MCAP recording.

    """
    if not Path(path).is_file():
        raise RecordingError(f"recording {path} does not exist")
    topics: dict[str, _Topic] = {}
    try:
        for segment in segments(path):
            with open(segment, "rb") as stream:
                reader = make_reader(stream)
                for schema, channel, message in reader.iter_messages(log_time_order=True):
                    topic = topics.get(channel.topic)
                    if topic is None:
                        topic = topics[channel.topic] = _Topic(
                            schema.name if schema else "",
                            channel.message_encoding,
                            bytes(schema.data) if schema else b"",
                        )
                    topic.messages.append((message.publish_time, bytes(message.data)))
    except (McapError, OSError, ValueError, EOFError, KeyError) as exc:
        raise RecordingError(
            f"{path} is not a readable MCAP recording ({type(exc).__name__}: {exc}); "
            "`atr mcap check` names the problem, `atr mcap recover` repairs a file cut short"
        ) from exc
    return topics


def _aligned(messages: list[tuple[int, bytes]]) -> dict[tuple[int, int], bytes]:
    """Payloads keyed by (stamp_ns, order among the topic's messages of that stamp)."""
    out: dict[tuple[int, int], bytes] = {}
    seen: dict[int, int] = {}
    for stamp, payload in messages:
        k = seen.get(stamp, 0)
        seen[stamp] = k + 1
        out[(stamp, k)] = payload
    return out


def diff_recordings(
    base: str | Path, new: str | Path, tolerances: Tolerances | None = None
) -> DiffReport:
    """Compare the data messages of two recordings topic by topic and frame by frame.

    Args:
        base: the reference recording (a baseline).
        new: the recording under test.
        tolerances: the rules in force (None: the defaults, everything else exact).

    Returns:
        Per-topic results (sorted by topic) and per-frame results.

    Raises:
        RecordingError: a file is missing or unreadable, or a topic carries different message types or
            encodings in the two (a schema mismatch: the recordings cannot be compared).

    """
    tolerances = tolerances or Tolerances.defaults()
    base_topics, new_topics = _read(base), _read(new)
    report = DiffReport(base=str(base), new=str(new))
    for name in sorted(base_topics.keys() | new_topics.keys()):
        a, b = base_topics.get(name), new_topics.get(name)
        if (
            a is not None
            and b is not None
            and (a.message_type, a.encoding)
            != (
                b.message_type,
                b.encoding,
            )
        ):
            raise RecordingError(
                f"schema mismatch on {name}: {a.message_type or 'no schema'} ({a.encoding}) in "
                f"{base} but {b.message_type or 'no schema'} ({b.encoding}) in {new}"
            )
        either = a or b
        topic = TopicDiff(
            name,
            message_type=either.message_type,
            ignored=tolerances.topic_ignored(name),
            base_messages=len(a.messages) if a else 0,
            new_messages=len(b.messages) if b else 0,
            schema_changed=a is not None and b is not None and a.schema != b.schema,
        )
        report.topics.append(topic)
        if not topic.ignored:
            _compare_topic(topic, a, b, tolerances, report)
    return report


def _compare_topic(
    topic: TopicDiff, a: _Topic | None, b: _Topic | None, tolerances: Tolerances, report: DiffReport
) -> None:
    base = _aligned(a.messages) if a else {}
    new = _aligned(b.messages) if b else {}
    for key in sorted(base.keys() | new.keys()):
        stamp = key[0]
        difference: FieldDifference | None = None
        if key not in new:
            result = ONLY_BASE
            topic.only_base.append(stamp)
            difference = FieldDifference("<message>", _describe(base[key]), "<none>")
        elif key not in base:
            result = ONLY_NEW
            topic.only_new.append(stamp)
            difference = FieldDifference("<message>", "<none>", _describe(new[key]))
        elif base[key] == new[key]:
            result = IDENTICAL
            topic.identical += 1
        else:
            result, difference = _compare_payloads(topic, base[key], new[key], tolerances)
        if difference is not None and topic.first is None:
            topic.first = (stamp, difference)
        frame = report.frames.setdefault(stamp, {})
        previous = frame.get(topic.topic)
        if previous is None or worst(previous[0], result) != previous[0]:
            frame[topic.topic] = (result, difference)


def _compare_payloads(
    topic: TopicDiff, base: bytes, new: bytes, tolerances: Tolerances
) -> tuple[str, FieldDifference | None]:
    try:
        decoded = codec.unpack(base), codec.unpack(new)
    except AtrError as exc:  # a payload recorded as evidence need not decode
        topic.differing += 1
        return DIFFERS, FieldDifference(
            "<payload>", f"{len(base)} bytes", f"{len(new)} bytes", f"not comparable: {exc}"
        )
    comparison = compare_messages(topic.topic, *decoded, tolerances)
    if comparison.equal:
        topic.tolerated += 1
        if comparison.tolerated == 0:  # equal values in other bytes (e.g. map order)
            return WITHIN_TOLERANCE, FieldDifference(
                "<payload>", short(base), short(new), "equal values, other bytes"
            )
        return WITHIN_TOLERANCE, None
    topic.differing += 1
    return DIFFERS, comparison.differences[0]


def _describe(payload: bytes) -> str:
    """What a message without a partner says, in a few words (an error's reason, the targets seen)."""
    try:
        message = codec.unpack(payload)
    except AtrError:
        return f"undecodable message of {len(payload)} bytes"
    if not isinstance(message, dict):
        return short(message)
    if "reason" in message:
        return short(f"{message.get('error_type', 'error')}: {message['reason']}")
    if isinstance(message.get("detections"), list):
        targets = [d.get("target", "?") for d in message["detections"] if isinstance(d, dict)]
        return f"Detections seq {message.get('seq')}: [{', '.join(targets)}]"
    return f"message seq {message.get('seq')}"
