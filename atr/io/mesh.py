"""Target and confuser meshes: a vehicle of the simulator's family by name, or a mesh file.

A *mesh source* is a string, one of:

- a vehicle name of `atr.sim.vehicles.VEHICLES` ("t72", "leopard2", "btr80", ...): the vehicle built
  in code, with its own paints;
- a mesh file, PLY, OBJ, STL, GLB/GLTF or OFF (what Open3D reads), optionally followed by options:
  ``tank.glb``, ``tank.stl:units=mm``, ``tank.obj:up=y,forward=-z``.

File options (what the file's numbers mean; the mesh is brought to the vehicle frame: metres, z up,
x forward):

- ``units``: m, cm, mm, in or ft (default m).
- ``up``: the file's axis that points up: x, y, z, -x, -y or -z. Default z, except for GLB/GLTF,
  whose specification fixes +y up and +z forward.
- ``forward``: the file's axis that points to the vehicle's front (default x; z for GLB/GLTF). The
  recognition does not need it (it estimates the heading), the world uses it to drive a target
  along its street.

A file mesh is one triangle soup: real CAD files are often many loose parts, duplicated vertices,
degenerate triangles or hollow shells, and only the outer surface matters to the renderer, the LIDAR
and the template builder, so loading merges everything and drops what cannot be rendered (degenerate
or NaN triangles). A mesh whose longest side is not a vehicle's (`VEHICLE_EXTENT_M`) after its units,
or which is taller than it is long (a y-up file read as z-up), is refused with the option that
fixes it. Per-triangle materials are not read from files: a file mesh gets the `default` material
(or the one given).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d

from atr.errors import InputError
from atr.sim import materials as M
from atr.sim.mesh import Mesh
from atr.sim.vehicles import VEHICLES, vehicle

_EXTENSIONS = (".ply", ".obj", ".stl", ".glb", ".gltf", ".off")
_GLTF = (".glb", ".gltf")  # the glTF 2.0 specification: metres, +y up, +z forward
SAVE_EXTENSIONS = (".ply", ".obj", ".stl", ".off")
"""The file types `save_mesh` writes."""

UNITS_M: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
"""Length of one file unit, metres."""

AXES: dict[str, tuple[float, float, float]] = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}
"""The file axes ``up`` and ``forward`` may name."""

VEHICLE_EXTENT_M = (0.5, 30.0)
"""The longest side a ground vehicle's mesh may have, metres (a car is ~4.5 m, a tank with its gun
~11 m): outside, the file's units are almost surely not metres."""


@dataclass(frozen=True)
class MeshSource:
    """A parsed mesh source.

    Attributes:
        name: the target's or confuser's name in truth and templates: the vehicle name, or the file's
            stem.
        path: the mesh file; None for a vehicle built in code.
        units: file units (a key of `UNITS_M`).
        up: the file's up axis (a key of `AXES`).
        forward: the file's forward axis (a key of `AXES`).

    """

    name: str
    path: Path | None = None
    units: str = "m"
    up: str = "z"
    forward: str = "x"

    @property
    def options(self) -> str:
        """The file options that differ from the file format's defaults, as written after ':'."""
        if self.path is None:
            return ""
        default = _default_options(self.path)
        given = {"units": self.units, "up": self.up, "forward": self.forward}
        return ",".join(f"{k}={v}" for k, v in given.items() if v != default[k])


def _default_options(path: Path) -> dict[str, str]:
    gltf = path.suffix.lower() in _GLTF
    return {"units": "m", "up": "y" if gltf else "z", "forward": "z" if gltf else "x"}


def parse_source(source: str | Path) -> MeshSource:
    """Parse a mesh source: a vehicle name, or a mesh file with optional ``:key=value,...`` options.

    A `Path` is always a file, without options.

    Raises:
        InputError: an unknown vehicle name, an unsupported file extension, or a bad option.

    """
    if isinstance(source, Path):
        return _file_source(source, {})
    text = str(source)
    head, sep, tail = text.rpartition(":")
    options: dict[str, str] = {}
    if sep and "=" in tail:  # "file:key=value,..." (a ':' inside a path has no '=' after it)
        text = head
        for item in tail.split(","):
            key, eq, value = item.partition("=")
            if not eq or key not in ("units", "up", "forward"):
                raise InputError(
                    f"mesh option {item!r} in {source!r}: expected units=, up= or forward="
                )
            options[key] = value
    if Path(text).suffix.lower() in _EXTENSIONS:
        return _file_source(Path(text), options)
    if text in VEHICLES and not options:
        return MeshSource(text)
    if text in VEHICLES:
        raise InputError(f"vehicle {text!r} is built in code: it takes no file options ({tail!r})")
    raise InputError(
        f"mesh source {text!r} is neither a vehicle ({', '.join(VEHICLES)}) nor a mesh file "
        f"({', '.join(_EXTENSIONS)})"
    )


def _file_source(path: Path, options: dict[str, str]) -> MeshSource:
    if path.suffix.lower() not in _EXTENSIONS:
        raise InputError(
            f"mesh file {path} has extension {path.suffix!r}; expected one of {_EXTENSIONS}"
        )
    chosen = _default_options(path) | options
    if chosen["units"] not in UNITS_M:
        raise InputError(f"units={chosen['units']} for {path}: expected one of {list(UNITS_M)}")
    for key in ("up", "forward"):
        if chosen[key] not in AXES:
            raise InputError(f"{key}={chosen[key]} for {path}: expected one of {list(AXES)}")
    if np.dot(AXES[chosen["up"]], AXES[chosen["forward"]]) != 0.0:
        raise InputError(
            f"up={chosen['up']} and forward={chosen['forward']} for {path} must be different axes"
        )
    return MeshSource(path.stem, path, chosen["units"], chosen["up"], chosen["forward"])


def resolve_source(source: str | Path) -> str:
    """The source as a string that means the same from any working folder: a vehicle name as it is,
    a file as its absolute path (with its options).

    Raises:
        InputError: as `parse_source`.

    """
    parsed = parse_source(source)
    if parsed.path is None:
        return parsed.name
    options = parsed.options
    return str(parsed.path.resolve()) + (f":{options}" if options else "")


def mesh_name(source: str | Path) -> str:
    """The name a mesh source gives its vehicle in truth and templates (vehicle name or file stem)."""
    return parse_source(source).name


def vehicle_sources(
    target: str | None,
    target_mesh: str | None,
    clutter: Sequence[str] = (),
    clutter_mesh: Sequence[str] = (),
) -> tuple[str | None, tuple[str, ...]]:
    """The target and the extra confusers the command-line options choose, each checked to load.

    Args:
        target: ``--target``: a vehicle name (None: the T-72, unless target_mesh is given).
        target_mesh: ``--target-mesh``: a mesh file with optional options.
        clutter: ``--clutter``: vehicle names of extra confusers.
        clutter_mesh: ``--clutter-mesh``: mesh files of extra confusers.

    Returns:
        The target's mesh source (None: the T-72) and the confusers' mesh sources, names first.

    Raises:
        InputError: both target options, a name where a file is expected or the reverse, a
            source that does not load (`load_mesh`), or a confuser that is the target itself.

    """
    if target is not None and target_mesh is not None:
        raise InputError(f"give --target {target} or --target-mesh {target_mesh}, not both")
    for flag, sources, is_file in (
        ("--target", [target] if target else [], False),
        ("--clutter", clutter, False),
        ("--target-mesh", [target_mesh] if target_mesh else [], True),
        ("--clutter-mesh", clutter_mesh, True),
    ):
        for source in sources:
            if (parse_source(source).path is not None) != is_file:
                wanted = "a mesh file" if is_file else f"a vehicle name ({', '.join(VEHICLES)})"
                raise InputError(f"{flag} {source}: expected {wanted}")
            load_mesh(source)
    chosen = target if target is not None else target_mesh
    target_name = mesh_name(chosen) if chosen is not None else "t72"
    confusers = (*clutter, *clutter_mesh)
    for source in confusers:
        if mesh_name(source) == target_name:
            raise InputError(f"confuser {source} is the target {target_name} itself")
    return chosen, tuple(confusers)


def load_mesh(source: str | Path, material: int = M.DEFAULT) -> Mesh:
    """The mesh of a mesh source, in the vehicle frame (metres, z up, x forward).

    Args:
        source: a vehicle name, or a mesh file with optional options (module docstring).
        material: material index given to every triangle of a file mesh (a vehicle built in code
            keeps its paints).

    Raises:
        InputError: unknown vehicle, missing file, unsupported extension, bad option, no usable
            triangles, or a size no vehicle has (the message names the option to give).

    """
    parsed = parse_source(source)
    if parsed.path is None:
        return vehicle(parsed.name)
    v, t = _read_triangles(parsed.path)
    scale, R = UNITS_M[parsed.units], _file_to_vehicle(parsed.up, parsed.forward)
    if scale != 1.0 or not np.array_equal(R, np.eye(3)):  # metres, z up, x forward: as read
        v = (v * scale) @ R.T
    _check_vehicle_size(v, parsed, str(source))
    used, inv = np.unique(t.ravel(), return_inverse=True)
    material_ids = np.full(t.shape[0], material, np.int16)
    return Mesh(v[used], inv.reshape(-1, 3).astype(np.int32), material_ids)


def _read_triangles(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) in file units and the finite, non-degenerate triangles (M, 3) of a file."""
    if not path.is_file():
        raise InputError(f"mesh file {path} does not exist")
    tm = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False)
    v = np.asarray(tm.vertices, dtype=np.float64)
    t = np.asarray(tm.triangles, dtype=np.int64)
    if v.shape[0] == 0 or t.shape[0] == 0:
        raise InputError(f"mesh file {path} holds no triangles")
    good_v = np.all(np.isfinite(v), axis=1)
    t = t[np.all(good_v[t], axis=1)]
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    t = t[area2 > 1e-12]
    if t.shape[0] == 0:
        raise InputError(f"mesh file {path} holds only degenerate triangles")
    return v, t


def _file_to_vehicle(up: str, forward: str) -> np.ndarray:
    """(3, 3) rotation taking the file's up axis to +z and its forward axis to +x."""
    u, f = np.array(AXES[up]), np.array(AXES[forward])
    return np.vstack([f, np.cross(u, f), u])


def _check_vehicle_size(v: np.ndarray, source: MeshSource, text: str) -> None:
    extent = v.max(axis=0) - v.min(axis=0)
    longest = float(extent.max())
    lo, hi = VEHICLE_EXTENT_M
    if not lo <= longest <= hi:
        raise InputError(
            f"mesh {text} is {longest:.4g} m long in units={source.units}, a vehicle {lo:g}-{hi:g} m: "
            f"give the file's units, e.g. {source.path}:units=mm"
        )
    if extent[2] > max(extent[0], extent[1]):
        raise InputError(
            f"mesh {text} is taller ({extent[2]:.3g} m along z) than it is long: with up={source.up} "
            "the vehicle stands on its end; give the file's up axis, e.g. "
            f"{source.path}:up=y (glTF and many OBJ exports are y-up)"
        )


def save_mesh(mesh: Mesh, path: str | Path) -> None:
    """Write a Mesh to PLY/OBJ/STL/OFF by extension (metres, z up, x forward), making its folders.

    Not glTF: its specification wants y up, and Open3D's GLB writer makes files its own reader refuses.

    Raises:
        InputError: unsupported extension, empty mesh, or the writer failed.

    """
    p = Path(path)
    if p.suffix.lower() not in SAVE_EXTENSIONS:
        raise InputError(
            f"mesh file {p} has extension {p.suffix!r}; can write {', '.join(SAVE_EXTENSIONS)}"
        )
    if mesh.n_triangles == 0:
        raise InputError(f"refusing to write an empty mesh to {p}")
    p.parent.mkdir(parents=True, exist_ok=True)
    tm = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(mesh.vertices),
        o3d.utility.Vector3iVector(mesh.triangles.astype(np.int32)),
    )
    tm.compute_triangle_normals()
    if p.suffix.lower() == ".stl":
        tm.compute_vertex_normals()
    if not o3d.io.write_triangle_mesh(str(p), tm, write_ascii=False):
        raise InputError(f"could not write mesh file {p}")
