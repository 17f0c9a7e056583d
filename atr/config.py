"""The one typed configuration of the system: every subsystem's config group in one tree.

Every group is a frozen dataclass defined next to its algorithm (`atr/<pkg>/config.py`) and validated in its
constructor. This module gathers them and applies overrides written as `group.field=value`, the form used by
`--set` on the command line, by the layouts in `compose/`, and by YAML files (nested maps).

    config = load_config(overrides=["sfm.matcher=surf", "recognition.descriptor=fpfh"])

The SfM defaults to the arm that measures best on held-out targets: dense matching (`sfm.matcher=sgm`,
ours; docs/evaluation), with the matcher confirming the targets it holds between whole searches
(`tracking.guided_search`, ours; docs/tracking.md). A preset is a named list of overrides, given as
`preset=NAME` among them (`--preset paper` on the command line, `preset: paper` in a YAML file); it
applies where it stands, so a later override refines it. `preset=paper` is the paper's sparse GFTT/KLT SfM deciding each scene alone, the
evaluation's `gftt-sfm` arm.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from atr.baselines2d.config import Baseline2dConfig
from atr.errors import ConfigError
from atr.imu.config import ImuConfig
from atr.recognition.config import RecognitionConfig
from atr.sfm.config import SfmConfig
from atr.sim.config import SimConfig
from atr.tracking.config import TrackingConfig


@dataclass(frozen=True)
class PipelineConfig:
    """How the services are wired around the algorithms.

    Attributes:
        targets: target names the template store serves and the matcher looks for: the T-72 and the
            simulator's confusers, so the matcher says which vehicle it sees (recognition, not detection).
        target_meshes: extra CAD mesh files (PLY/OBJ/STL/GLB, z up, metres, x forward); each is a target
            named after its file stem.
        cloud_source: which cloud the matcher reads: "sfm" (the paper's pipeline) or "lidar" (the baseline).
        template_timeout_s: how long the matcher waits for a template query before reporting an error.

    """

    targets: tuple[str, ...] = ("t72", "ifv", "truck6x6")
    target_meshes: tuple[str, ...] = ()
    cloud_source: Literal["sfm", "lidar"] = "sfm"
    template_timeout_s: float = 600.0
    compact_clouds: bool = False

    def __post_init__(self) -> None:
        if not self.targets and not self.target_meshes:
            raise ConfigError(
                "pipeline.targets and pipeline.target_meshes are both empty: nothing to recognise"
            )
        if self.template_timeout_s <= 0:
            raise ConfigError(f"pipeline.template_timeout_s {self.template_timeout_s} must be > 0")


@dataclass(frozen=True)
class AtrConfig:
    """Everything a flight's processing depends on; saved with every result."""

    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    # The camera-IMU extrinsic is a property of the camera head; by default it is the simulated head's.
    imu: ImuConfig = field(default_factory=lambda: ImuConfig(T_imu_cam=SimConfig().T_imu_cam))
    # Dense SfM, the arm that measures best on held-out targets; PRESETS["paper"] is the paper's.
    sfm: SfmConfig = field(default_factory=lambda: SfmConfig(matcher="sgm"))
    recognition: RecognitionConfig = field(default_factory=RecognitionConfig)
    baselines2d: Baseline2dConfig = field(default_factory=Baseline2dConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)


PRESETS: dict[str, tuple[str, ...]] = {
    "dense": ("sfm.matcher=sgm", "tracking.guided_search=true"),
    "paper": ("sfm.matcher=gftt", "tracking.guided_search=false"),
}
"""Named override lists (`preset=NAME`). "dense": the default, semi-global matching of the pair rectified
with the known pose, searching whole scenes only until a target is held and then every fourth scene
(track-guided search; ours). "paper": the paper's sparse GFTT/KLT SfM (§II-B-1) deciding each scene alone,
exactly as the evaluation's gftt-sfm arm runs it. What that arm adds to
the paper's text keeps its own switch (the pose-aided KLT pass: `sfm.klt_aided_pyramid_levels=0`;
docs/sfm.md)."""


def _coerce(value: Any, annotation: Any, where: str) -> Any:
    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        if value not in typing.get_args(annotation):
            raise ConfigError(f"{where}={value!r}; expected one of {typing.get_args(annotation)}")
        return value
    if origin in (typing.Union, types.UnionType):
        options = typing.get_args(annotation)
        if value is None and type(None) in options:
            return None
        for option in options:
            if option is type(None):
                continue
            try:
                return _coerce(value, option, where)
            except ConfigError:
                continue
        raise ConfigError(f"{where}={value!r} fits none of {options}")
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where}={value!r}; expected a list")
        args = typing.get_args(annotation)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0], where) for v in value)
        return tuple(_coerce(v, a, where) for v, a in zip(value, args, strict=True))
    if annotation is float and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if annotation in (int, str, bool) and not isinstance(value, annotation):
        raise ConfigError(f"{where}={value!r}; expected {annotation.__name__}")
    return value


def _with(config: Any, path: list[str], value: Any, where: str) -> Any:
    if not dataclasses.is_dataclass(config):
        raise ConfigError(f"{where}: {type(config).__name__} has no fields")
    hints = typing.get_type_hints(type(config))
    if path[0] not in hints and hasattr(config, "field_path"):  # a group routing names to its parts
        path = [*config.field_path(path[0]), *path[1:]]
    name = path[0]
    if name not in hints:
        fields = sorted(f.name for f in dataclasses.fields(config))
        raise ConfigError(f"{where}: unknown field {name!r}; expected one of {fields}")
    if len(path) > 1:
        new = _with(getattr(config, name), path[1:], value, where)
    elif isinstance(value, dict):
        new = getattr(config, name)
        for key, item in value.items():
            new = _with(new, [key], item, f"{where}.{key}")
    else:
        new = _coerce(value, hints[name], where)
    return dataclasses.replace(config, **{name: new})


def apply_overrides(config: Any, overrides: list[str] | dict[str, Any]) -> Any:
    """A copy of dataclass `config` with `a.b=value` overrides (values parsed as YAML scalars/lists);
    `preset=NAME` applies the overrides of ``PRESETS[NAME]`` where it stands.

    Raises:
        ConfigError: unknown field or preset, value of the wrong type, or a value its group's
            validation refuses.

    """
    items = overrides.items() if isinstance(overrides, dict) else [_split(o) for o in overrides]
    for dotted, value in items:
        if dotted == "preset":
            config = apply_overrides(config, list(_preset(value)))
        else:
            config = _with(config, dotted.split("."), value, dotted)
    return config


def _preset(name: Any) -> tuple[str, ...]:
    if not isinstance(name, str) or name not in PRESETS:
        raise ConfigError(f"preset {name!r} is unknown; expected one of {sorted(PRESETS)}")
    return PRESETS[name]


def _split(override: str) -> tuple[str, Any]:
    if "=" not in override:
        raise ConfigError(f"override {override!r} must look like group.field=value")
    dotted, text = override.split("=", 1)
    try:
        return dotted.strip(), yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"override {override!r}: {exc}") from exc


def load_config(path: str | Path | None = None, overrides: list[str] | None = None) -> AtrConfig:
    """The defaults, then a YAML file of nested groups, then `group.field=value` overrides.

    Raises:
        ConfigError: unreadable file or invalid value.

    """
    config = AtrConfig()
    if path is not None:
        try:
            data = yaml.safe_load(Path(path).read_text()) or {}
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f"config file {path}: {exc}") from exc
        if not isinstance(data, dict):
            raise ConfigError(f"config file {path} must hold a map of groups")
        config = apply_overrides(config, data)
    return apply_overrides(config, overrides or [])


def to_dict(config: Any) -> dict[str, Any]:
    """The config as plain data (for saving next to results)."""
    return dataclasses.asdict(config)
