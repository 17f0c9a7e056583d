r"""Run the 3D matcher (paper §II-B-2) on a model file and a scene file, and print what it recognised.

The model is a point cloud (used as the viewed model P_m) or a mesh (a CAD model: sampled, hidden points
removed from aerial viewpoints, §II-A). The scene is a point cloud or a mesh (sampled). Files: PCD, PLY, XYZ,
OBJ, STL, GLB, OFF.

Examples:
    atr recognize --model t72.ply --scene cloud.pcd --descriptor shot
    atr recognize --model milk.pcd --scene milk_cartoon_all_small_clorox.pcd --descriptor fpfh \\
        --resolution auto --viewpoint 0 0 0 --json
    atr recognize --model tank.obj --scene lidar.xyz --descriptor hod-s --resolution 0.3 --seed 7

With --json the output is one JSON object (a contract tools rely on):
    {"detections": [{"target", "descriptor", "T_world_target", "score", "overlap", "inliers"}],
     "stage_times_ms": {...}, "resolution_m": R, "stats": {...}}

"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from atr.io.geometry import Geometry

AUTO_SPACING_FACTOR = 6.0
"""--resolution auto on a small model: this many mean point spacings (PCL's tutorial works in multiples of
the model's mean spacing; 6 x 1.5 mm ~ 1 cm for its milk carton)."""
VEHICLE_EXTENT_M = 3.0
"""--resolution auto keeps the paper's 0.3 m for models at least this large (vehicle-sized)."""
MAX_RESOLUTION_M = 100.0
"""A larger --resolution leaves no vehicle more than a point: refused as a mistake."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Register the options of `atr recognize`."""
    parser.add_argument("--model", required=True, help="model file: point cloud or mesh")
    parser.add_argument("--scene", required=True, help="scene file: point cloud or mesh")
    parser.add_argument(
        "--descriptor",
        default="shot",
        choices=("shot", "usc", "3dsc", "fpfh", "rops", "hod", "hod-s"),
        help="3D descriptor (default shot)",
    )
    parser.add_argument(
        "--resolution",
        default="auto",
        help="subsampling resolution in metres, or 'auto': the paper's 0.3 m for vehicle-sized models "
        f"(>= {VEHICLE_EXTENT_M} m), else {AUTO_SPACING_FACTOR:g} x the model's mean point spacing",
    )
    parser.add_argument(
        "--target", default=None, help="target name (default: the model's file stem)"
    )
    parser.add_argument("--seed", type=int, default=0, help="RANSAC seed (default 0)")
    parser.add_argument(
        "--viewpoint",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        default=None,
        help="sensor position for normal orientation (default: normals face up, +z)",
    )
    parser.add_argument(
        "--views",
        type=int,
        default=None,
        help="mesh model only: number of HPR azimuths whose union is the template (default: config)",
    )
    parser.add_argument(
        "--max-keypoints",
        type=int,
        default=None,
        help="describe at most this many scene vertices (deterministic thinning; default: config)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def _resolution(arg: str, model_points, is_mesh: bool) -> float:
    import numpy as np

    from atr.errors import ConfigError
    from atr.recognition.io import mean_spacing_m

    if arg != "auto":
        try:
            value = float(arg)
        except ValueError as exc:
            raise ConfigError(f"--resolution {arg!r} must be a number of metres or 'auto'") from exc
        if not 0 < value <= MAX_RESOLUTION_M:
            raise ConfigError(
                f"--resolution {arg!r} must be > 0 and <= {MAX_RESOLUTION_M:g} metres, or 'auto'"
            )
        return value
    pts = model_points[np.isfinite(model_points).all(axis=1)]
    extent = float(np.linalg.norm(pts.max(0) - pts.min(0))) if len(pts) else 0.0
    if is_mesh or extent >= VEHICLE_EXTENT_M:
        return 0.3
    return AUTO_SPACING_FACTOR * mean_spacing_m(pts)


@contextlib.contextmanager
def _start_up() -> Iterator[None]:
    """No cyclic garbage collection while the libraries are imported and the files read; then what they
    made is set aside for good (`gc.freeze`), and collection goes on for the rest.

    Start-up makes ~170,000 objects that live as long as the process (the numba, SciPy and Open3D
    modules and numba's typing tables). The collector walked all of them again and again: three full
    passes while importing and one more at exit, ~0.5 s of CPU on PCL's milk scene (bench/startup.py).
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if was_enabled:
            gc.enable()


def _read_inputs(args: argparse.Namespace) -> tuple[Geometry, Geometry]:
    """The model and scene files, and the arguments that need no matcher: a bad one is refused before
    the matcher's imports (~1 s).
    """
    from atr.errors import InputError
    from atr.io.geometry import MAX_ABS_COORDINATE_M, load_geometry

    model = load_geometry(args.model)
    scene = load_geometry(args.scene)
    if len(model.points) == 0:
        raise InputError(f"{args.model}: the model holds no point")
    if args.viewpoint is not None and not all(
        abs(v) <= MAX_ABS_COORDINATE_M for v in args.viewpoint
    ):
        raise InputError(
            f"--viewpoint {args.viewpoint} must be finite and within ±{MAX_ABS_COORDINATE_M:g} m"
        )
    if args.max_keypoints is not None and args.max_keypoints < 1:
        raise InputError(f"--max-keypoints {args.max_keypoints} must be >= 1")
    return model, scene


def run(args: argparse.Namespace) -> int:
    """Load the files, build the template, run the matcher, print detections and stage times."""
    import dataclasses
    from pathlib import Path

    with _start_up():
        import numpy as np

        from atr.errors import InputError

        model, scene = _read_inputs(args)
        from atr.recognition import (
            RecognitionConfig,
            build_template,
            recognize,
            sample_mesh_surface,
            template_from_points,
        )

    resolution = _resolution(args.resolution, model.points, model.is_mesh)
    config = RecognitionConfig(resolution_m=resolution, descriptor=args.descriptor)
    if args.max_keypoints is not None:
        config = dataclasses.replace(config, max_scene_keypoints=args.max_keypoints)
    if args.views is not None:
        if args.views < 1:
            raise InputError(f"--views {args.views} must be >= 1")
        azimuths = tuple(360.0 * i / args.views for i in range(args.views))
        config = dataclasses.replace(config, template_azimuths_deg=azimuths)
    target = args.target or Path(args.model).stem
    viewpoint = None if args.viewpoint is None else np.asarray(args.viewpoint, np.float64)
    if model.is_mesh:
        template = build_template(model.points, model.triangles, target, args.descriptor, config)
    else:
        template = template_from_points(
            model.points, target, args.descriptor, config, viewpoint=viewpoint
        )
    if scene.is_mesh:
        density = 1.0 / (0.25 * resolution) ** 2  # several samples per voxel
        scene_points, _ = sample_mesh_surface(
            scene.points, scene.triangles, density, seed=args.seed
        )
    else:
        scene_points = scene.points
    result = recognize(scene_points, [template], config, seed=args.seed, viewpoint_m=viewpoint)

    stats = {k: v for k, v in result.stats.items() if k != "verified"}
    if args.json:
        out = {
            "detections": [d.to_dict() for d in result.detections],
            "stage_times_ms": {k: round(v, 3) for k, v in result.stage_times_ms.items()},
            "resolution_m": resolution,
            "stats": stats,
        }
        json.dump(out, sys.stdout)
        sys.stdout.write("\n")
        return 0
    print(f"resolution {resolution:.4g} m, descriptor {args.descriptor}, target {target!r}")
    if not result.detections:
        reason = result.stats.get("reason", "no hypothesis passed verification")
        print(f"no detection ({reason})")
    for i, d in enumerate(result.detections):
        print(
            f"detection {i}: {d.target} score {d.score:.1f} overlap {d.overlap:.3f} inliers {d.inliers}"
        )
        for row in np.asarray(d.T_world_target):
            print("    " + " ".join(f"{v: .6f}" for v in row))
    print(
        "stage times (ms): " + ", ".join(f"{k} {v:.1f}" for k, v in result.stage_times_ms.items())
    )
    return 0
