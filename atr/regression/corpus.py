"""A regression corpus: recordings, their per-recording settings, and the provenance of their baselines.

A corpus is a directory of recordings (`NAME.mcap`), each with an optional `NAME.yml` holding the config
groups it is replayed with (the same format as any config file, e.g. `pipeline: {targets: [t72]}`). A
baseline directory holds, per recording, the replay it is compared with (`NAME.mcap`) and how that was
made (`NAME.json`: code version, source hash, config).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from atr.config import load_config, to_dict
from atr.errors import ConfigError, InputError
from atr.provenance import file_sha256, source_commit, source_sha256

REPO = Path(__file__).resolve().parents[2]
_SEGMENT = re.compile(r"\.\d+\.mcap$")  # flight.1.mcap: a later segment of flight.mcap


@dataclass(frozen=True)
class CorpusEntry:
    """One recording of a corpus and the settings it is replayed with.

    Attributes:
        name: the recording's file name without `.mcap`.
        path: the recording.
        overrides: `group.field=value` settings from its `NAME.yml`, then the command line's.

    """

    name: str
    path: Path
    overrides: tuple[str, ...]


def _flatten(data: Any, prefix: str, where: Path) -> list[str]:
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: {prefix or 'the file'} must be a map of config groups")
    out = []
    for key, value in data.items():
        dotted = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            out += _flatten(value, dotted, where)
        else:
            out.append(
                f"{dotted}={json.dumps(value)}"
            )  # JSON is YAML: the override parser reads it
    return out


def load_corpus(
    corpus_dir: str | Path, extra_overrides: list[str] | None = None
) -> list[CorpusEntry]:
    """The recordings of `corpus_dir` (sorted by name) with their settings.

    Raises:
        InputError: the directory does not exist or holds no recording.
        ConfigError: a settings file is unreadable or sets an unknown or invalid field.

    """
    corpus_dir = Path(corpus_dir)
    if not corpus_dir.is_dir():
        raise InputError(f"corpus {corpus_dir} is not a directory")
    paths = sorted(
        p
        for p in corpus_dir.glob("*.mcap")
        if not _SEGMENT.search(p.name) and not p.name.endswith("-foxglove.mcap")
    )
    if not paths:
        raise InputError(f"corpus {corpus_dir} holds no recording (*.mcap)")
    entries = []
    for path in paths:
        settings = path.with_suffix(".yml")
        overrides: list[str] = []
        if settings.is_file():
            try:
                data = yaml.safe_load(settings.read_text()) or {}
            except (OSError, yaml.YAMLError) as exc:
                raise ConfigError(f"settings {settings}: {exc}") from exc
            overrides = _flatten(data, "", settings)
        overrides += list(extra_overrides or [])
        load_config(None, overrides)  # refuse a bad setting before any replay starts
        entries.append(CorpusEntry(path.stem, path, tuple(overrides)))
    return entries


def baseline_provenance(entry: CorpusEntry, layout: str, frames: int) -> dict[str, Any]:
    """What a baseline was made with: the recording, the code version, the config and the layout."""
    return {
        "recording": entry.path.name,
        "recording_sha256": file_sha256(entry.path),
        "frames": frames,
        "code_version": source_commit(),
        "source_sha256": source_sha256(),
        "layout": layout,
        "overrides": list(entry.overrides),
        "config": to_dict(load_config(None, list(entry.overrides))),
    }
