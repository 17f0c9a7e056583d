"""The message registry: one JSON Schema per message type in `schemas/`, the single source of truth.

Array fields use this project's `ndarray` keyword (allowed dtypes, shape with null for any length, finite or not,
and optionally `min_shape` (least length of each axis), `max_abs` (the largest magnitude a value may have: the
physical range of the field) and `rule` (what the shape means, said when it does not match)).
`validator(name)` returns a jsonschema validator that checks `ndarray` fields on the numpy arrays themselves,
so validation never copies an array payload.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
from jsonschema import validators

from atr.errors import SchemaError

SCHEMA_DIR = Path(__file__).resolve().parents[1] / "schemas"


def names() -> list[str]:
    """Names of every registered message type, sorted."""
    return sorted(p.stem for p in SCHEMA_DIR.glob("*.json"))


@cache
def load(name: str) -> dict[str, Any]:
    """The JSON Schema of message type `name` (e.g. "Image").

    Raises:
        SchemaError: no schema of that name exists.

    """
    path = SCHEMA_DIR / f"{name}.json"
    if not path.is_file():
        raise SchemaError(f"unknown message type {name!r}; expected one of {names()}")
    return json.loads(path.read_text())


@cache
def schema_bytes(name: str) -> bytes:
    """The schema as compact UTF-8 JSON, as written into MCAP files."""
    return json.dumps(load(name), separators=(",", ":"), sort_keys=True).encode()


def _check_ndarray(validator: Any, spec: dict[str, Any], instance: Any, schema: Any):  # noqa: ANN202
    if not isinstance(instance, np.ndarray):
        yield jsonschema.ValidationError(f"expected a numpy array, got {type(instance).__name__}")
        return
    dtypes = spec.get("dtype")
    if dtypes and instance.dtype.name not in dtypes:
        yield jsonschema.ValidationError(f"dtype {instance.dtype.name} not in {dtypes}")
        return
    shape = spec.get("shape")
    if shape is not None:
        if instance.ndim != len(shape) or any(
            want is not None and want != got
            for want, got in zip(shape, instance.shape, strict=True)
        ):
            expected = tuple("N" if s is None else s for s in shape)
            rule = f" ({spec['rule']})" if "rule" in spec else ""
            yield jsonschema.ValidationError(
                f"shape {instance.shape} does not match {expected}{rule}"
            )
            return
    least = spec.get("min_shape")
    if least is not None and any(got < want for want, got in zip(least, instance.shape)):
        yield jsonschema.ValidationError(
            f"shape {instance.shape} is too small; expected at least {tuple(least)}"
        )
        return
    if spec.get("finite") and instance.dtype.kind == "f" and not np.isfinite(instance).all():
        yield jsonschema.ValidationError(
            f"array of shape {instance.shape} has NaN or infinite values"
        )
        return
    bound = spec.get("max_abs")
    if bound is not None and instance.size:
        # Finite but absurd values (1e30 m) would overflow the grids and integer casts downstream.
        low, high = float(instance.min()), float(instance.max())  # a float16 cannot hold the bound
        if low < -bound or high > bound:
            worst = low if -low > high else high
            index = tuple(int(i) for i in np.argwhere(instance == instance.dtype.type(worst))[0])
            yield jsonschema.ValidationError(
                f"value {float(worst):g} at index {list(index)} is outside the allowed range "
                f"[{-bound:g}, {bound:g}]"
            )


def _is_object(checker: Any, instance: Any) -> bool:
    return isinstance(instance, dict)


_Validator = validators.extend(
    jsonschema.Draft202012Validator,
    validators={"ndarray": _check_ndarray},
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("object", _is_object),
)


@cache
def validator(name: str) -> Any:
    """A cached validator for message type `name`."""
    return _Validator(load(name))


def validate(name: str, message: dict[str, Any]) -> None:
    """Check `message` against the schema of `name`.

    Raises:
        SchemaError: naming the first offending field and what was expected.

    """
    error = jsonschema.exceptions.best_match(validator(name).iter_errors(message))
    if error is not None:
        where = "/".join(str(p) for p in error.absolute_path) or "<message>"
        raise SchemaError(f"{name} field {where}: {error.message}")
