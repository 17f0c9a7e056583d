"""Point cloud and mesh files for the matcher (`atr recognize`): read whole, or refused with the reason.

PCD and XYZ files are clouds; a PLY is a mesh when it has faces (read by the strict reader in
`atr.io.ply`); OBJ, STL, GLB/GLTF and OFF are meshes read through Open3D. A file that cannot be read whole is
refused, never used in part; so is a position beyond `MAX_ABS_COORDINATE_M` (a finite but absurd 1e30 m
overflows the matcher's grids) or an infinite one. NaN rows of a PCD file (organised clouds) are kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atr.errors import InputError

MAX_ABS_COORDINATE_M = 100_000.0
"""The largest coordinate magnitude a file may hold, metres: the bus's bound on positions (`max_abs` in
schemas/), 100 km from the origin."""
CLOUD_SUFFIXES = (".pcd", ".xyz", ".xyzn", ".txt", ".pts")
MESH_SUFFIXES = (".obj", ".stl", ".glb", ".gltf", ".off")


@dataclass
class Geometry:
    """What a file held.

    Attributes:
        points: (N, 3) float64 metres (the mesh vertices for a mesh); NaN rows of a PCD file are kept.
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
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a whitespace-separated XYZ file ({exc})") from exc
    if data.size == 0:
        return np.zeros((0, 3))
    if data.shape[1] < 3:
        raise InputError(f"{path}: rows have {data.shape[1]} columns; expected at least x y z")
    return data[:, :3].astype(np.float64)


def _read_mesh(path: Path) -> Geometry:
    import open3d as o3d  # a second of start-up, paid only for these formats

    mesh = o3d.io.read_triangle_mesh(str(path))
    if len(mesh.triangles) == 0:
        raise InputError(f"{path}: could not read any triangle")
    return Geometry(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.triangles, np.int64))


def check_positions(points: np.ndarray, path: str | Path) -> None:
    """Refuse infinite positions and finite ones beyond `MAX_ABS_COORDINATE_M` (NaN rows pass).

    Raises:
        InputError: naming the file, the row and the value.

    """
    with np.errstate(invalid="ignore"):
        bad = np.isinf(points) | (np.abs(points) > MAX_ABS_COORDINATE_M)
    if bad.any():
        row, column = (int(i) for i in np.argwhere(bad)[0])
        raise InputError(
            f"{path}: point {row} has {'xyz'[column]} = {points[row, column]:g}; expected a finite "
            f"coordinate within ±{MAX_ABS_COORDINATE_M:g} m"
        )


def load_geometry(path: str | Path) -> Geometry:
    """Read a point cloud or a mesh file, whole.

    Args:
        path: PCD, XYZ (.xyz .xyzn .txt .pts), PLY, OBJ, STL, GLB/GLTF or OFF file, metres.

    Returns:
        The file's points (vertices) and, for a mesh, its triangles.

    Raises:
        InputError: the path is missing or a directory, the file type is unknown, the file cannot be read
            whole (the reason named), or a position is infinite or beyond `MAX_ABS_COORDINATE_M`.

    """
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{p} is a directory; expected a point cloud or mesh file")
    if not p.is_file():
        raise InputError(f"{p}: no such file")
    suffix = p.suffix.lower()
    if suffix == ".pcd":
        from atr.io.pcd import read_pcd_xyz

        geometry = Geometry(read_pcd_xyz(p), None)
    elif suffix in CLOUD_SUFFIXES:
        geometry = Geometry(_read_xyz(p), None)
    elif suffix == ".ply":
        from atr.io.ply import read_ply

        ply = read_ply(p)
        geometry = Geometry(ply.points, ply.triangles if len(ply.triangles) else None)
    elif suffix in MESH_SUFFIXES:
        geometry = _read_mesh(p)
    else:
        raise InputError(
            f"{p}: unknown file type {suffix!r}; expected one of "
            f"{' '.join((*CLOUD_SUFFIXES, '.ply', *MESH_SUFFIXES))}"
        )
    check_positions(geometry.points, p)
    return geometry
