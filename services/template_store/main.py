"""template_store: the offline phase (§II-A) as a service — CAD meshes -> 3D templates, served on demand.

For every target (the T-72 and the simulator's confusers, plus any `pipeline.target_meshes` file) and
descriptor it builds the template (dense surface sampling, hidden point removal from the aerial view(s),
uniform subsampling at 0.3 m, description), caches it on disk keyed by the mesh's content and every parameter,
and answers queries on `atr/templates/{target}/{descriptor}`. The configured descriptor's templates are built
before the service reports ready; other descriptors are built on their first query.

Example:
    atr service template_store --set recognition.descriptor=fpfh --cache templates/
    atr service template_store --set "pipeline.target_meshes=[my_tank.ply]"

"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import threading
from pathlib import Path

from atr.config import AtrConfig
from atr.recognition import DESCRIPTORS, build_template
from atr.recognition.template import TEMPLATE_VERSION
from bus import codec
from bus.launcher import REPO
from bus.service import effective_config, service_arguments, start_node

log = logging.getLogger("atr")


def target_meshes(config: AtrConfig) -> dict[str, object]:
    """Target name -> Mesh, built-in vehicles first, then mesh files (named by file stem)."""
    from atr.io.mesh import load_mesh  # noqa: PLC0415 - Open3D import only when needed
    from atr.sim.vehicles import VEHICLES  # noqa: PLC0415

    meshes: dict[str, object] = {name: VEHICLES[name]() for name in config.pipeline.targets}
    for path in config.pipeline.target_meshes:
        meshes[Path(path).stem] = load_mesh(path)
    return meshes


def cache_key(mesh: object, descriptor: str, config: AtrConfig) -> str:
    """Content hash of the mesh and every parameter that shapes the template."""
    params = dataclasses.asdict(config.recognition) | {
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
        path = self.cache_dir / f"{target}-{descriptor}-{key}.msgpack"
        if path.exists():
            try:
                return codec.decode("Template", path.read_bytes())
            except Exception as exc:  # a damaged cache file is rebuilt, not trusted
                log.warning("cache file %s unreadable (%s); rebuilding", path, exc)
        config = dataclasses.replace(self.config.recognition, descriptor=descriptor)
        template = build_template(mesh.vertices, mesh.triangles, target, descriptor, config)
        data = template.to_dict()
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
            "descriptors": data["descriptors"],
            "params": json.loads(json.dumps(data["params"], default=str)),
        }
        self.cache_dir.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(codec.encode("Template", message))
        tmp.replace(path)
        log.info(
            "built template %s/%s: %d keypoints, %.2f KB",
            target,
            descriptor,
            len(data["keypoints_m"]),
            (data["descriptors"].nbytes + data["keypoints_m"].nbytes) / 1024,
        )
        return message


def main(argv: list[str] | None = None) -> int:
    """Run the service until stopped."""
    parser = service_arguments("template_store", __doc__)
    parser.add_argument(
        "--cache", type=Path, default=REPO / "templates", help="template cache folder"
    )
    args = parser.parse_args(argv)
    config = effective_config(args)
    with start_node("template_store", args, inputs=[]) as node:
        store = TemplateStore(config, args.cache)
        for target in store.meshes:
            store.message(target, config.recognition.descriptor)

        def answer(key: str) -> dict | None:
            _, _, target, descriptor = key.split("/")
            return store.message(target, descriptor)

        node.serve("atr/templates/*/*", answer)
        node.ready()
        for _ in node.events():
            pass
    return 0
