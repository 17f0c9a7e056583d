"""Mesh files: load any PLY/OBJ/STL/GLB/OFF through Open3D into an `atr.sim.Mesh`, save one back.

Real CAD files are often many loose parts, duplicated vertices, degenerate triangles or hollow
shells; only the outer surface matters to the renderer, the LIDAR and the template builder, so
loading merges everything into one triangle soup and drops what cannot be rendered (degenerate or
NaN triangles). Per-triangle materials are not read from files: a loaded mesh gets the `default`
material (or the one given). Saving writes geometry (PLY/OBJ/STL...) and, for PLY, vertex colours of
the material.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import open3d as o3d

from atr.errors import InputError
from atr.sim import materials as M
from atr.sim.mesh import Mesh

_EXTENSIONS = (".ply", ".obj", ".stl", ".glb", ".gltf", ".off")


def load_mesh(path: str | Path, material: int = M.DEFAULT) -> Mesh:
    """Read a triangle mesh file (metres, z up, x forward) into a Mesh.

    Args:
        path: PLY, OBJ, STL, GLB/GLTF or OFF file.
        material: material index given to every triangle.

    Raises:
        InputError: missing file, unsupported extension, or no usable triangles.

    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"mesh file {p} does not exist")
    if p.suffix.lower() not in _EXTENSIONS:
        raise InputError(f"mesh file {p} has extension {p.suffix!r}; expected one of {_EXTENSIONS}")
    tm = o3d.io.read_triangle_mesh(str(p), enable_post_processing=False)
    v = np.asarray(tm.vertices, dtype=np.float64)
    t = np.asarray(tm.triangles, dtype=np.int64)
    if v.shape[0] == 0 or t.shape[0] == 0:
        raise InputError(f"mesh file {p} holds no triangles")
    good_v = np.all(np.isfinite(v), axis=1)
    t = t[np.all(good_v[t], axis=1)]
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    t = t[area2 > 1e-12]
    if t.shape[0] == 0:
        raise InputError(f"mesh file {p} holds only degenerate triangles")
    used, inv = np.unique(t.ravel(), return_inverse=True)
    material_ids = np.full(t.shape[0], material, np.int16)
    return Mesh(v[used], inv.reshape(-1, 3).astype(np.int32), material_ids)


def save_mesh(mesh: Mesh, path: str | Path) -> None:
    """Write a Mesh to PLY/OBJ/STL/GLB/OFF (by extension); parent folders are created.

    Raises:
        InputError: unsupported extension, empty mesh, or the writer failed.

    """
    p = Path(path)
    if p.suffix.lower() not in _EXTENSIONS:
        raise InputError(f"mesh file {p} has extension {p.suffix!r}; expected one of {_EXTENSIONS}")
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
