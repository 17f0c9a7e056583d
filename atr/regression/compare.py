"""Field-by-field comparison of two decoded messages (msgpack maps with numpy arrays), under tolerances.

Exact by default: numbers, strings and lists must be equal, arrays must have the same dtype, shape and
bytes. A tolerance rule (`atr.regression.tolerances`) can accept a numeric difference (abs/rel), a pose
difference of a 4x4 `T_*` array (metres/degrees), or ignore a field. Lists of detections (maps with
`target` and `T_world_target`) are compared as what they mean: each base detection is paired with the
nearest new detection of the same target, and the pair is compared by pose (metres, degrees), score and
the other fields; a detection without a partner is a difference of its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from atr.regression.tolerances import Rule, Tolerances

MAX_LISTED = 10  # differences listed per message (all are counted)


@dataclass(frozen=True)
class FieldDifference:
    """One field that differs beyond its tolerance.

    Attributes:
        path: where, e.g. `detections[t72#0].T_world_target` or `points_m[12,1]`.
        base: the base value, shortened for display.
        new: the new value, shortened for display.
        detail: how much it differs, and the tolerance it broke, when that says more than the values.

    """

    path: str
    base: str
    new: str
    detail: str = ""

    def describe(self) -> str:
        """One line: path, both values and the detail."""
        detail = f" ({self.detail})" if self.detail else ""
        return f"{self.path}: {self.base} -> {self.new}{detail}"


@dataclass
class Comparison:
    """What comparing two messages found.

    Attributes:
        differences: the first `MAX_LISTED` differences, in field order.
        count: every difference found.
        tolerated: fields that differed within their tolerance.

    """

    differences: list[FieldDifference] = field(default_factory=list)
    count: int = 0
    tolerated: int = 0

    @property
    def equal(self) -> bool:
        """True when nothing differs beyond its tolerance."""
        return self.count == 0

    def add(self, difference: FieldDifference) -> None:
        """Count a difference, keeping the first few."""
        self.count += 1
        if len(self.differences) < MAX_LISTED:
            self.differences.append(difference)


def pose_difference(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """Translation difference (metres) and rotation angle (degrees) between two (4, 4) poses.

    The angle comes from the chord ||R_a - R_b||_F = 2 sqrt(2) sin(angle / 2), which stays accurate for
    the tiny angles a regression looks for (the arccos of the trace does not).
    """
    a = np.asarray(T_a, dtype=np.float64)
    b = np.asarray(T_b, dtype=np.float64)
    metres = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    chord = float(np.linalg.norm(a[:3, :3] - b[:3, :3])) / (2.0 * np.sqrt(2.0))
    degrees = float(np.degrees(2.0 * np.arcsin(min(chord, 1.0))))
    return metres, degrees


def compare_messages(
    topic: str, base: Any, new: Any, tolerances: Tolerances | None = None
) -> Comparison:
    """Compare two decoded messages of `topic` field by field.

    Args:
        topic: the topic both came from (tolerance rules are chosen by it).
        base: the baseline's message.
        new: the new message.
        tolerances: the rules in force (None: everything exact).

    Returns:
        The differences beyond tolerance and the count of differences within it.

    """
    result = Comparison()
    _Walk(topic, tolerances or Tolerances(), result).compare(base, new, "", "")
    return result


def short(value: Any) -> str:
    """A short display of a value: arrays by dtype and shape, long strings cut."""
    if isinstance(value, np.ndarray):
        if value.size <= 4:
            return np.array2string(value.ravel(), precision=17, separator=", ")
        return f"{value.dtype}[{'x'.join(str(n) for n in value.shape)}]"
    if isinstance(value, list):
        return f"list of {len(value)}"
    if isinstance(value, dict):
        return f"map of {len(value)}"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _within(rule: Rule | None, base: Any, new: Any) -> Any:
    if rule is None or not (rule.abs or rule.rel):
        return False
    base = np.asarray(base, dtype=np.float64)
    new = np.asarray(new, dtype=np.float64)
    close = np.abs(new - base) <= rule.abs + rule.rel * np.abs(base)
    return close | (np.isnan(base) & np.isnan(new))


def _tolerance_text(rule: Rule | None) -> str:
    if rule is None:
        return "exact"
    parts = [
        f"{k} {getattr(rule, k):g}" for k in ("abs", "rel", "metres", "degrees") if getattr(rule, k)
    ]
    return ", ".join(parts) or "exact"


def _is_detection_list(base: Any, new: Any) -> bool:
    items = [*base, *new]
    return bool(items) and all(
        isinstance(d, dict) and "target" in d and "T_world_target" in d for d in items
    )


class _Walk:
    def __init__(self, topic: str, tolerances: Tolerances, result: Comparison) -> None:
        self.topic = topic
        self.tolerances = tolerances
        self.result = result

    def compare(self, base: Any, new: Any, path: str, rule_path: str) -> None:
        rule = self.tolerances.rule_for(self.topic, rule_path) if rule_path else None
        if rule is not None and rule.ignore:
            return
        if isinstance(base, dict) and isinstance(new, dict):
            self._maps(base, new, path, rule_path)
        elif isinstance(base, list) and isinstance(new, list):
            if _is_detection_list(base, new):
                self._detections(base, new, path, rule_path)
            else:
                self._lists(base, new, path, rule_path)
        elif isinstance(base, np.ndarray) and isinstance(new, np.ndarray):
            self._arrays(base, new, path, rule_path, rule)
        elif _is_number(base) and _is_number(new):
            self._numbers(base, new, path, rule)
        elif type(base) is not type(new) or base != new:
            self.result.add(FieldDifference(path or "<message>", short(base), short(new)))

    def _maps(self, base: dict, new: dict, path: str, rule_path: str) -> None:
        for key in [*base, *(k for k in new if k not in base)]:
            sub = f"{path}.{key}" if path else str(key)
            sub_rule = f"{rule_path}.{key}" if rule_path else str(key)
            if key not in new or key not in base:
                rule = self.tolerances.rule_for(self.topic, sub_rule)
                if rule is None or not rule.ignore:
                    self.result.add(
                        FieldDifference(
                            sub,
                            short(base[key]) if key in base else "<missing>",
                            short(new[key]) if key in new else "<missing>",
                        )
                    )
                continue
            self.compare(base[key], new[key], sub, sub_rule)

    def _lists(self, base: list, new: list, path: str, rule_path: str) -> None:
        if len(base) != len(new):
            self.result.add(
                FieldDifference(path, f"{len(base)} items", f"{len(new)} items", "lengths differ")
            )
        for i, (a, b) in enumerate(zip(base, new, strict=False)):
            self.compare(a, b, f"{path}[{i}]", rule_path)

    def _detections(self, base: list, new: list, path: str, rule_path: str) -> None:
        unpaired = list(range(len(new)))
        for i, a in enumerate(base):
            label = f"{path}[{a['target']}#{i}]"
            same_target = [j for j in unpaired if new[j]["target"] == a["target"]]
            if not same_target:
                self.result.add(FieldDifference(label, _detection_text(a), "<none>", "target lost"))
                continue
            j = min(
                same_target,
                key=lambda j: pose_difference(a["T_world_target"], new[j]["T_world_target"])[0],
            )
            unpaired.remove(j)
            self.compare(a, new[j], label, rule_path)
        for j in unpaired:
            label = f"{path}[{new[j]['target']}#new{j}]"
            self.result.add(FieldDifference(label, "<none>", _detection_text(new[j]), "new target"))

    def _arrays(
        self, base: np.ndarray, new: np.ndarray, path: str, rule_path: str, rule: Rule | None
    ) -> None:
        if base.dtype != new.dtype or base.shape != new.shape:
            self.result.add(
                FieldDifference(path, short(base), short(new), "dtype or shape differs")
            )
            return
        if base.tobytes() == new.tobytes():
            return
        name = rule_path.rsplit(".", 1)[-1]
        if base.shape == (4, 4) and name.startswith("T_") and base.dtype.kind == "f":
            metres, degrees = pose_difference(base, new)
            text = f"moved {metres:.3g} m, turned {degrees:.3g} deg"
            if rule is not None and (rule.metres or rule.degrees) and not (rule.abs or rule.rel):
                if metres <= rule.metres and degrees <= rule.degrees:
                    self.result.tolerated += 1
                    return
                self.result.add(
                    FieldDifference(
                        path, short(base[:3, 3]), short(new[:3, 3]), text + _beyond(rule)
                    )
                )
                return
            if not np.all(_within(rule, base, new)):
                self.result.add(
                    FieldDifference(
                        path, short(base[:3, 3]), short(new[:3, 3]), text + _beyond(rule)
                    )
                )
                return
            self.result.tolerated += 1
            return
        if base.dtype.kind in "biuf":
            close = _within(rule, base, new)
            if close is not False and np.all(close):
                self.result.tolerated += 1
                return
            if close is False:
                unequal = base != new
                if base.dtype.kind == "f":
                    unequal &= ~(np.isnan(base) & np.isnan(new))
            else:
                unequal = ~close
            if not unequal.any():  # equal values in other bytes: -0.0 against 0.0, NaN payloads
                self.result.add(
                    FieldDifference(path, short(base), short(new), "same values, other bytes")
                )
                return
            first = tuple(int(n) for n in np.argwhere(unequal)[0])
            where = f"{path}[{','.join(str(n) for n in first)}]"
            delta = np.abs(base.astype(np.float64) - new.astype(np.float64))
            self.result.add(
                FieldDifference(
                    where,
                    repr(base[first].item()),
                    repr(new[first].item()),
                    f"{int(unequal.sum())} of {base.size} elements differ, "
                    f"max |diff| {np.nanmax(delta):.3g}{_beyond(rule)}",
                )
            )

    def _numbers(self, base: float, new: float, path: str, rule: Rule | None) -> None:
        if base == new or (base != base and new != new):  # NaN == NaN here
            return
        if isinstance(base, float) or isinstance(new, float):
            if bool(_within(rule, base, new)):
                self.result.tolerated += 1
                return
        self.result.add(
            FieldDifference(
                path, repr(base), repr(new), f"|diff| {abs(new - base):.3g}{_beyond(rule)}"
            )
        )


def _beyond(rule: Rule | None) -> str:
    return f" > {_tolerance_text(rule)}" if rule is not None else ""


def _detection_text(detection: dict) -> str:
    x, y, z = np.asarray(detection["T_world_target"])[:3, 3]
    return f"{detection['target']} at ({x:.2f}, {y:.2f}, {z:.2f}) score {detection.get('score', 0):.4g}"
