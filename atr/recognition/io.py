"""File readers for the matcher: point clouds (PCD, PLY, XYZ) and meshes (PLY, OBJ, STL, GLB, OFF)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atr.errors import InputError

MESH_SUFFIXES = (".obj", ".stl", ".glb", ".gltf", ".off")
CLOUD_SUFFIXES = (".pcd", ".xyz", ".xyzn", ".txt", ".pts")


@dataclass
class Geometry:
    """What a file held.

    Attributes:
        points: (N, 3) float64 metres (the mesh vertices for a mesh); NaN rows are kept.
        triangles: (M, 3) int64 vertex indices, or None for a point cloud.

    """

    points: np.ndarray
    triangles: np.ndarray | None

    @property
    def is_mesh(self) -> bool:
        """True when the file held triangles."""
        return self.triangles is not None and len(self.triangles) > 0


def _read_xyz(path: Path) -> np.ndarray:
    try:
        data = np.loadtxt(path, ndmin=2, comments="#")
    except ValueError as exc:
        raise InputError(f"{path}: not a whitespace-separated XYZ file ({exc})") from exc
    if data.size == 0:
        return np.zeros((0, 3))
    if data.shape[1] < 3:
        raise InputError(f"{path}: rows have {data.shape[1]} columns; expected at least x y z")
    return data[:, :3].astype(np.float64)


def _read_pcd(path: Path) -> np.ndarray:
    try:
        from atr.io.pcd import read_pcd_xyz
    except ImportError:  # pragma: no cover - depends on the checkout
        import open3d as o3d

        cloud = o3d.io.read_point_cloud(
            str(path), remove_nan_points=False, remove_infinite_points=False
        )
        return np.asarray(cloud.points, np.float64)
    return np.asarray(read_pcd_xyz(path), np.float64)


def load_geometry(path: str | Path) -> Geometry:
    """Read a point cloud or a mesh file.

    PCD and XYZ files are clouds; OBJ, STL, GLB, OFF are meshes; a PLY is a mesh when it has faces.

    Raises:
        InputError: the file is missing, unreadable, or of an unknown type.

    """
    import open3d as o3d

    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such file")
    suffix = p.suffix.lower()
    if suffix == ".pcd":
        return Geometry(_read_pcd(p), None)
    if suffix in (".xyz", ".xyzn", ".txt", ".pts"):
        return Geometry(_read_xyz(p), None)
    if suffix in (".ply", *MESH_SUFFIXES):
        mesh = o3d.io.read_triangle_mesh(str(p))
        if len(mesh.triangles) > 0:
            return Geometry(
                np.asarray(mesh.vertices, np.float64), np.asarray(mesh.triangles, np.int64)
            )
        if suffix == ".ply":
            cloud = o3d.io.read_point_cloud(
                str(p), remove_nan_points=False, remove_infinite_points=False
            )
            return Geometry(np.asarray(cloud.points, np.float64), None)
        raise InputError(f"{p}: could not read any triangle")
    raise InputError(
        f"{p}: unknown file type {suffix!r}; expected one of .pcd .ply .xyz {' '.join(MESH_SUFFIXES)}"
    )


def mean_spacing_m(points: np.ndarray) -> float:
    """Mean distance of each finite point to its nearest neighbour, metres (PCL's cloud resolution)."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) < 2:
        raise InputError(f"cloud has {len(pts)} finite points; a spacing needs at least 2")
    d, _ = cKDTree(pts).query(pts, k=2)
    return float(d[:, 1].mean())
