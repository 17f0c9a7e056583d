"""What `atr diff` found, per topic and per frame, and its outputs: a human summary, JUnit XML, JSON lines."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from atr.errors import InputError
from atr.regression.compare import FieldDifference

# Results of one aligned message (or frame), from best to worst.
IDENTICAL = "identical"
WITHIN_TOLERANCE = "within_tolerance"
DIFFERS = "differs"
ONLY_BASE = "only_base"
ONLY_NEW = "only_new"
_RANK = {IDENTICAL: 0, WITHIN_TOLERANCE: 1, ONLY_BASE: 2, ONLY_NEW: 2, DIFFERS: 3}


def worst(a: str, b: str) -> str:
    """The worse of two results."""
    return a if _RANK[a] >= _RANK[b] else b


@dataclass
class TopicDiff:
    """One topic of two recordings compared.

    Attributes:
        topic: the key expression.
        message_type: its schema name ("" for a channel without schema).
        ignored: a default or tolerance rule ignores the whole topic.
        base_messages: messages on the topic in the base recording.
        new_messages: messages on the topic in the new recording.
        identical: aligned pairs with equal bytes (never decoded).
        tolerated: aligned pairs that differ only within tolerances.
        differing: aligned pairs that differ beyond tolerances.
        only_base: stamp_ns of base messages without a partner in the new recording.
        only_new: stamp_ns of new messages without a partner in the base recording.
        first: the first difference (stamp_ns of its frame, the difference).
        schema_changed: the topic's JSON Schema text differs between the recordings (a note only: a
            schema's description may change without any message changing; the fields decide).

    """

    topic: str
    message_type: str = ""
    ignored: bool = False
    base_messages: int = 0
    new_messages: int = 0
    identical: int = 0
    tolerated: int = 0
    differing: int = 0
    only_base: list[int] = field(default_factory=list)
    only_new: list[int] = field(default_factory=list)
    first: tuple[int, FieldDifference] | None = None
    schema_changed: bool = False

    @property
    def same(self) -> bool:
        """True when the topic is ignored or nothing on it differs beyond tolerance."""
        return self.ignored or not (self.differing or self.only_base or self.only_new)

    def summary(self) -> str:
        """One line for a human: counts, and the first difference when there is one."""
        if self.ignored:
            return f"{self.topic}: ignored ({self.base_messages} / {self.new_messages} messages)"
        counts = f"{self.base_messages} / {self.new_messages} messages"
        note = f"; note: schema {self.message_type} text changed" if self.schema_changed else ""
        if self.same:
            hidden = f", {self.tolerated} within tolerance" if self.tolerated else ""
            return f"{self.topic}: same ({counts}{hidden}{note})"
        parts = [f"{self.differing} differ"] if self.differing else []
        if self.only_base:
            parts.append(f"{len(self.only_base)} only in base (first stamp {self.only_base[0]})")
        if self.only_new:
            parts.append(f"{len(self.only_new)} only in new (first stamp {self.only_new[0]})")
        line = f"{self.topic}: DIFFERS ({counts}; {', '.join(parts)}{note})"
        if self.first is not None:
            stamp, difference = self.first
            line += f"\n    first at stamp {stamp}: {difference.describe()}"
        return line


@dataclass
class DiffReport:
    """Two recordings compared: every topic, and the result of every frame (stamp_ns).

    Attributes:
        base: path of the base recording.
        new: path of the new recording.
        topics: per-topic results, sorted by topic.
        frames: stamp_ns -> topic -> (result, first difference or None), for the JSON lines.

    """

    base: str
    new: str
    topics: list[TopicDiff] = field(default_factory=list)
    frames: dict[int, dict[str, tuple[str, FieldDifference | None]]] = field(default_factory=dict)

    @property
    def same(self) -> bool:
        """True when every topic is the same (within tolerance) or ignored."""
        return all(t.same for t in self.topics)

    @property
    def differing_topics(self) -> list[TopicDiff]:
        """The topics that differ."""
        return [t for t in self.topics if not t.same]

    def summary(self) -> str:
        """A short human summary: one line per topic that differs, then a verdict."""
        compared = [t for t in self.topics if not t.ignored]
        lines = [t.summary() for t in self.differing_topics]
        tolerated = sum(t.tolerated for t in compared)
        if self.same:
            hidden = f"; {tolerated} messages within tolerance" if tolerated else ""
            lines.append(
                f"SAME: {len(compared)} data topics, "
                f"{sum(t.base_messages for t in compared)} messages{hidden}"
            )
        else:
            lines.append(
                f"DIFFERENT: {len(self.differing_topics)} of {len(compared)} data topics differ"
            )
        return "\n".join(lines)


def write_jsonl(report: DiffReport, path: str | Path) -> None:
    """One JSON line per compared frame (stamp_ns): its worst result and each topic's.

    Raises:
        InputError: the file cannot be written.

    """
    lines = []
    for stamp in sorted(report.frames):
        topics = report.frames[stamp]
        result = IDENTICAL
        entries = {}
        for topic, (topic_result, difference) in sorted(topics.items()):
            result = worst(result, topic_result)
            entry: dict[str, object] = {"result": topic_result}
            if difference is not None:
                entry["first_difference"] = {
                    "path": difference.path,
                    "base": difference.base,
                    "new": difference.new,
                    "detail": difference.detail,
                }
            entries[topic] = entry
        lines.append(json.dumps({"stamp_ns": stamp, "result": result, "topics": entries}))
    _write(path, "\n".join(lines) + ("\n" if lines else ""))


def junit_suite(report: DiffReport, name: str) -> ET.Element:
    """A JUnit `testsuite` element: one testcase per topic, a failure where it differs, skipped where
    ignored.
    """
    suite = ET.Element("testsuite", name=name)
    failures = skipped = 0
    for topic in report.topics:
        case = ET.SubElement(suite, "testcase", classname=name, name=topic.topic)
        if topic.ignored:
            ET.SubElement(case, "skipped", message="ignored (wall-clock or by a tolerance rule)")
            skipped += 1
        elif not topic.same:
            first = topic.first[1].describe() if topic.first else topic.summary().split("\n")[0]
            failure = ET.SubElement(case, "failure", message=first)
            failure.text = topic.summary()
            failures += 1
    suite.set("tests", str(len(report.topics)))
    suite.set("failures", str(failures))
    suite.set("skipped", str(skipped))
    suite.set("errors", "0")
    return suite


def write_junit(suites: list[ET.Element], path: str | Path) -> None:
    """Write `testsuites` holding `suites` as JUnit XML.

    Raises:
        InputError: the file cannot be written.

    """
    root = ET.Element("testsuites")
    root.extend(suites)
    ET.indent(root)
    _write(path, ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n")


def _write(path: str | Path, text: str) -> None:
    try:
        Path(path).write_text(text)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc}") from exc
