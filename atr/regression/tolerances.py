"""Tolerance rules of `atr diff`: which fields of which topics may differ, and by how much.

A tolerance file is YAML:

    rules:
      - topic: "atr/*/sfm/cloud"      # fnmatch glob on the topic ('*' also crosses '/')
        field: "points_m"             # glob on the field path: keys joined by '.', list positions left out
        abs: 1.0e-6                   # |new - base| <= abs + rel * |base|
        rel: 0.0
      - topic: "atr/*/detections"
        field: "detections.T_world_target"
        metres: 0.05                  # a pose (4x4 T_*): translation difference, metres
        degrees: 0.5                  # and rotation difference, degrees
      - topic: "atr/*/*/errors"
        field: "reason"
        ignore: true                  # never compared
      - topic: "atr/*/pose/camera"    # no field: the whole topic is ignored
        ignore: true

For a field, the last rule that matches both its topic and its path wins. Without a matching rule a field
must be exactly equal (bytes of arrays, values of numbers and strings).
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from atr.errors import ConfigError

_KEYS = {"topic", "field", "abs", "rel", "metres", "degrees", "ignore"}
_AMOUNTS = ("abs", "rel", "metres", "degrees")

# Keys and fields that carry wall-clock or process identity, never data (docs/regression.md).
DEFAULT_IGNORED_TOPICS = ("*/status", "*/timing")
DEFAULT_IGNORED_FIELDS = (("*/errors", "input_source"),)


@dataclass(frozen=True)
class Rule:
    """One tolerance rule: what it applies to and how much difference it accepts.

    Attributes:
        topic: fnmatch glob on the topic.
        field: fnmatch glob on the field path (None: the whole topic).
        abs: accepted absolute difference of numbers, in the field's unit.
        rel: accepted difference relative to the base value's magnitude.
        metres: accepted translation difference of a 4x4 pose, metres.
        degrees: accepted rotation difference of a 4x4 pose, degrees.
        ignore: the field (or topic) is not compared at all.

    """

    topic: str
    field: str | None = None
    abs: float = 0.0
    rel: float = 0.0
    metres: float = 0.0
    degrees: float = 0.0
    ignore: bool = False

    def matches(self, topic: str, path: str) -> bool:
        """True when the rule applies to `path` (keys joined by '.') of a message on `topic`."""
        if not fnmatch.fnmatchcase(topic, self.topic):
            return False
        return self.field is None or fnmatch.fnmatchcase(path, self.field)


@dataclass(frozen=True)
class Tolerances:
    """The rules in force: the defaults (wall-clock topics and fields ignored), then the user's."""

    rules: tuple[Rule, ...] = ()

    @classmethod
    def defaults(cls) -> Tolerances:
        """Only the default ignores: status and timing topics, `input_source` of ErrorReports."""
        return cls(
            tuple(Rule(topic=t, ignore=True) for t in DEFAULT_IGNORED_TOPICS)
            + tuple(Rule(topic=t, field=f, ignore=True) for t, f in DEFAULT_IGNORED_FIELDS)
        )

    def topic_ignored(self, topic: str) -> bool:
        """True when a topic-wide rule (no field) ignores `topic`."""
        rule = None
        for candidate in self.rules:
            if candidate.field is None and fnmatch.fnmatchcase(topic, candidate.topic):
                rule = candidate
        return rule is not None and rule.ignore

    def rule_for(self, topic: str, path: str) -> Rule | None:
        """The last rule matching `path` of a message on `topic`, or None (exact comparison)."""
        found = None
        for rule in self.rules:
            if rule.matches(topic, path):
                found = rule
        return found


def parse_tolerances(data: Any, where: str = "tolerances") -> Tolerances:
    """The defaults followed by the rules of a parsed tolerance document (`{"rules": [...]}`).

    Raises:
        ConfigError: not a map with a list of rules, an unknown key, a missing topic, a negative or
            non-numeric amount, or a rule that neither ignores nor accepts any difference.

    """
    if data is None:
        return Tolerances.defaults()
    if not isinstance(data, dict) or set(data) - {"rules"}:
        raise ConfigError(f"{where} must be a map with one key 'rules'; got {data!r:.80}")
    items = data.get("rules") or []
    if not isinstance(items, list):
        raise ConfigError(f"{where}: 'rules' must be a list of rules; got {items!r:.80}")
    rules = []
    for n, item in enumerate(items):
        at = f"{where}: rule {n + 1}"
        if not isinstance(item, dict):
            raise ConfigError(f"{at} must be a map; got {item!r:.80}")
        unknown = set(item) - _KEYS
        if unknown:
            raise ConfigError(f"{at} has unknown keys {sorted(unknown)}; expected {sorted(_KEYS)}")
        if not isinstance(item.get("topic"), str):
            raise ConfigError(f"{at} needs 'topic', a glob string; got {item.get('topic')!r}")
        field = item.get("field")
        if field is not None and not isinstance(field, str):
            raise ConfigError(f"{at}: 'field' must be a glob string; got {field!r}")
        amounts = {}
        for key in _AMOUNTS:
            value = item.get(key, 0.0)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
                raise ConfigError(f"{at}: '{key}' is {value!r}; expected a number >= 0")
            amounts[key] = float(value)
        ignore = item.get("ignore", False)
        if not isinstance(ignore, bool):
            raise ConfigError(f"{at}: 'ignore' is {ignore!r}; expected true or false")
        if not ignore and not any(amounts.values()):
            raise ConfigError(
                f"{at} ({item['topic']} {field or ''}) accepts no difference; "
                "give abs, rel, metres, degrees or ignore: true"
            )
        if field is None and not ignore:
            raise ConfigError(f"{at}: a rule without 'field' must be 'ignore: true'")
        rules.append(Rule(topic=item["topic"], field=field, ignore=ignore, **amounts))
    return Tolerances(Tolerances.defaults().rules + tuple(rules))


def load_tolerances(path: str | Path | None) -> Tolerances:
    """The tolerances of a YAML file (None: the defaults only).

    Raises:
        ConfigError: the file cannot be read, is not YAML, or holds an invalid rule.

    """
    if path is None:
        return Tolerances.defaults()
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f"tolerance file {path}: {exc}") from exc
    return parse_tolerances(data, where=f"tolerance file {path}")
