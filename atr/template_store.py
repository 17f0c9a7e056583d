"""The template store's core: CAD meshes -> 3D templates (the paper's offline phase, §II-A), cached on disk.

For every target (the configured vehicles, plus any `pipeline.target_meshes` file) and descriptor it builds the
template (dense surface sampling, hidden point removal from the aerial view(s), uniform subsampling,
description), caches it keyed by the mesh's content and every parameter, and hands it out as a Template
message (the cache file holds that message's arrays and fields, .npz). The template_store service serves these messages on
the bus; the evaluation builds its templates through the same object, so both use identical templates.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import threading
from pathlib import Path

import numpy as np

from atr.config import AtrConfig
from atr.io.mesh import load_mesh
from atr.recognition import DESCRIPTORS, build_template
from atr.recognition.template import (
    DESCRIPTOR_ARRAYS,
    TEMPLATE_VERSION,
    message_storage_bytes,
)
from atr.sim.vehicles import VEHICLES

log = logging.getLogger("atr")


def target_meshes(config: AtrConfig) -> dict[str, object]:
    """Target name -> Mesh, built-in vehicles first, then mesh files (named by file stem)."""
    meshes: dict[str, object] = {name: VEHICLES[name]() for name in config.pipeline.targets}
    for path in config.pipeline.target_meshes:
        meshes[Path(path).stem] = load_mesh(path)
    return meshes


def cache_key(mesh: object, descriptor: str, config: AtrConfig) -> str:
    """Content hash of the mesh and every parameter that shapes the template."""
    params = dataclasses.asdict(config.recognition.template) | {  # what shapes a template only
        "descriptor": descriptor,
        "version": TEMPLATE_VERSION,
    }
    digest = hashlib.sha256(json.dumps(params, sort_keys=True, default=str).encode())
    digest.update(mesh.vertices.tobytes())
    digest.update(mesh.triangles.tobytes())
    return digest.hexdigest()[:24]


class TemplateStore:
    """Builds, caches and hands out templates as Template messages."""

    def __init__(self, config: AtrConfig, cache_dir: Path) -> None:
        self.config = config
        self.cache_dir = cache_dir
        self.meshes = target_meshes(config)
        self._lock = threading.Lock()
        self._memory: dict[tuple[str, str], dict] = {}

    def message(self, target: str, descriptor: str) -> dict | None:
        """The Template message of `target` with `descriptor`, built if needed; None if unknown."""
        if target not in self.meshes or descriptor not in DESCRIPTORS:
            return None
        with self._lock:  # one build at a time; queries for a template being built wait for it
            if (target, descriptor) not in self._memory:
                self._memory[(target, descriptor)] = self._load_or_build(target, descriptor)
            return self._memory[(target, descriptor)]

    def _load_or_build(self, target: str, descriptor: str) -> dict:
        mesh = self.meshes[target]
        key = cache_key(mesh, descriptor, self.config)
        path = self.cache_dir / f"{target}-{descriptor}-{key}.npz"
        if path.exists():
            try:
                return _load(path)
            except Exception as exc:  # a damaged cache file is rebuilt, not trusted
                log.warning("cache file %s unreadable (%s); rebuilding", path, exc)
        config = dataclasses.replace(self.config.recognition, descriptor=descriptor)
        template = build_template(mesh.vertices, mesh.triangles, target, descriptor, config)
        data = template.to_dict(compact=config.template.compact_descriptors)
        message = {
            "stamp_ns": 0,
            "seq": 0,
            "version": 1,
            "target": target,
            "descriptor": descriptor,
            "cache_key": key,
            "radius_m": data["radius_m"],
            "resolution_m": config.resolution_m,
            "points_m": data["points_m"],
            "normals": data["normals"],
            "keypoints_m": data["keypoints_m"],
            **{n: data[n] for n in DESCRIPTOR_ARRAYS if n in data},
            "params": json.loads(json.dumps(data["params"], default=str)),
        }
        self.cache_dir.mkdir(parents=True, exist_ok=True)
        _save(path, message)
        log.info(
            "built template %s/%s: %d keypoints, %.2f KB",
            target,
            descriptor,
            len(data["keypoints_m"]),
            message_storage_bytes(message) / 1024,
        )
        return message


_ARRAYS = ("points_m", "normals", "keypoints_m", *DESCRIPTOR_ARRAYS)


def _save(path: Path, message: dict) -> None:
    """A Template message as .npz: the arrays as they are, the rest as JSON (exact for floats)."""
    # the key order too: the service's wire bytes must not depend on whether the cache was warm
    fields = {k: v for k, v in message.items() if k not in _ARRAYS}
    header = json.dumps({"order": list(message), "fields": fields}).encode()
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        np.savez(
            f,
            header=np.frombuffer(header, np.uint8),
            **{k: message[k] for k in _ARRAYS if k in message},
        )
    tmp.replace(path)


def _load(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as stored:
        header = json.loads(stored["header"].tobytes())
        values = header["fields"] | {k: stored[k] for k in _ARRAYS if k in stored}
    return {k: values[k] for k in header["order"]}
