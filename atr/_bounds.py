"""Config fields that carry their bounds, and the one check every config group runs on construction.

A group declares each field's bounds where it declares the field (pydantic's ``Field(gt=0)``, for frozen
dataclasses), and its ``__post_init__`` calls ``check_fields``:

    n_templates: int = bounded(12, ge=1)
    nndr_ratio: float = bounded(0.8, gt=0, le=1)

    def __post_init__(self) -> None:
        check_fields(self)

``check_fields`` refuses, with a ConfigError naming the field and the value: a bounded field that is not a
finite number or lies outside its bounds, and a ``bool`` field that is not true or false. None in a
bounded ``float | None`` field means "off" and is not checked.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

from atr.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class Bounds:
    """Where a config number may lie; every bound given must hold.

    Attributes:
        gt: the number must be greater than this.
        ge: at least this.
        lt: less than this.
        le: at most this.
        odd: the number must be an odd integer (window sides with a centre pixel).
        why: the reason for the bounds, quoted in the error message.

    """

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    odd: bool = False
    why: str = ""

    def admits(self, value: float) -> bool:
        """True when the value is a finite number within every bound."""
        return (
            math.isfinite(value)
            and (self.gt is None or value > self.gt)
            and (self.ge is None or value >= self.ge)
            and (self.lt is None or value < self.lt)
            and (self.le is None or value <= self.le)
            and (not self.odd or value % 2 == 1)
        )

    def __str__(self) -> str:
        """The bounds as an error message states them: "a finite number > 0 and <= 1"."""
        signs = ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le))
        conditions = " and ".join(f"{sign} {bound:g}" for sign, bound in signs if bound is not None)
        text = f"{'an odd integer' if self.odd else 'a finite number'} {conditions}".rstrip()
        return f"{text} ({self.why})" if self.why else text


def bounded(default: float | None, **bounds: Any) -> Any:
    """A dataclass field with a default and the bounds ``check_fields`` holds it to (see ``Bounds``)."""
    return dataclasses.field(default=default, metadata={"bounds": Bounds(**bounds)})


def check_fields(group: Any, prefix: str = "", numbers_default: Bounds | None = None) -> None:
    """Refuse a config group whose bounded fields or flags hold a bad value.

    Args:
        group: a dataclass instance whose fields were declared with ``bounded``.
        prefix: put before a field's name in the message (the group's name, e.g. "tracking.").
        numbers_default: the bounds of every ``int`` or ``float`` field declared without any (a group
            whose numbers are all positive multiples says so once).

    Raises:
        ConfigError: naming the field, the bad value and the bounds.

    """
    for f in dataclasses.fields(group):
        value = getattr(group, f.name)
        if f.type in ("bool", bool) and not isinstance(value, bool):
            raise ConfigError(f"{prefix}{f.name} = {value!r} must be true or false")
        bounds = f.metadata.get("bounds")
        if bounds is None and f.type in ("int", "float", int, float):
            bounds = numbers_default
        if bounds is None or (value is None and "None" in str(f.type)):
            continue
        is_number = isinstance(value, numbers.Real) and not isinstance(value, bool)
        if not is_number or not bounds.admits(value):
            raise ConfigError(f"{prefix}{f.name} = {value!r} must be {bounds}")
