"""Triangle meshes with a material per triangle, and the primitives the simulated world is built
from.

Every mesh is in metres, z up, x forward (vehicles) and carries one material index per triangle into
`atr.sim.materials.MATERIALS`. The solid primitives (box, extruded profile, loft, cylinder,
ellipsoid) are closed, their faces counter-clockwise seen from outside. The renderer and the LIDAR
only look at the first surface a ray meets, either side; the template builder orients its normals
by the winding, so a vehicle mesh should be closed and wound outward.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from atr.errors import InputError


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh: metres, z up, x forward.

    Attributes:
        vertices: (V, 3) float64, metres.
        triangles: (M, 3) int32, vertex indices, counter-clockwise seen from outside.
        material: (M,) int16, index into `atr.sim.materials.MATERIALS`.

    """

    vertices: np.ndarray
    triangles: np.ndarray
    material: np.ndarray

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        t = np.ascontiguousarray(self.triangles, dtype=np.int32).reshape(-1, 3)
        m = np.ascontiguousarray(self.material, dtype=np.int16).reshape(-1)
        if m.shape[0] != t.shape[0]:
            raise InputError(f"mesh has {t.shape[0]} triangles but {m.shape[0]} material entries")
        if t.size and (t.min() < 0 or t.max() >= v.shape[0]):
            raise InputError(
                f"triangle indices must lie in [0, {v.shape[0]}), got [{t.min()}, {t.max()}]"
            )
        if not np.all(np.isfinite(v)):
            raise InputError("mesh vertices contain NaN or infinite values")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "triangles", t)
        object.__setattr__(self, "material", m)

    @property
    def n_triangles(self) -> int:
        """Number of triangles."""
        return int(self.triangles.shape[0])

    def transformed(self, T: np.ndarray) -> Mesh:
        """The mesh moved by a 4x4 rigid transform T (new = T @ old)."""
        T = np.asarray(T, dtype=np.float64)
        v = self.vertices @ T[:3, :3].T + T[:3, 3]
        return Mesh(v, self.triangles, self.material)

    def with_material(self, material: int) -> Mesh:
        """The same geometry with every triangle set to one material."""
        return Mesh(self.vertices, self.triangles, np.full(self.n_triangles, material, np.int16))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds (min (3,), max (3,)), metres."""
        if self.vertices.shape[0] == 0:
            raise InputError("empty mesh has no bounds")
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def triangle_areas(self) -> np.ndarray:
        """(M,) float64 triangle areas, m²."""
        a, b, c = (self.vertices[self.triangles[:, i]] for i in range(3))
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)

    def sample_surface(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) float64 points drawn uniformly over the surface area."""
        areas = self.triangle_areas()
        total = areas.sum()
        if total <= 0:
            raise InputError("mesh has zero surface area")
        idx = rng.choice(self.n_triangles, size=n, p=areas / total)
        r1 = np.sqrt(rng.random(n))
        r2 = rng.random(n)
        a, b, c = (self.vertices[self.triangles[idx, i]] for i in range(3))
        return (1 - r1)[:, None] * a + (r1 * (1 - r2))[:, None] * b + (r1 * r2)[:, None] * c


def merge(meshes: Sequence[Mesh]) -> Mesh:
    """Concatenate meshes into one (vertex indices shifted)."""
    meshes = [m for m in meshes if m.n_triangles > 0]
    if not meshes:
        return Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros(0, np.int16))
    offsets = np.cumsum([0] + [m.vertices.shape[0] for m in meshes[:-1]])
    return Mesh(
        np.concatenate([m.vertices for m in meshes]),
        np.concatenate([m.triangles + o for m, o in zip(meshes, offsets, strict=True)]),
        np.concatenate([m.material for m in meshes]),
    )


# transforms ---------------------------------------------------------------------------------------


def rot_z(yaw_rad: float) -> np.ndarray:
    """3x3 rotation about z."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(pitch_rad: float) -> np.ndarray:
    """3x3 rotation about y."""
    c, s = np.cos(pitch_rad), np.sin(pitch_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_x(roll_rad: float) -> np.ndarray:
    """3x3 rotation about x."""
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def pose(R: np.ndarray | None = None, t: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 homogeneous transform from a rotation and a translation."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = t
    return T


def place(mesh: Mesh, x: float, y: float, z: float = 0.0, yaw_rad: float = 0.0) -> Mesh:
    """Mesh rotated about z by yaw, then moved to (x, y, z)."""
    return mesh.transformed(pose(rot_z(yaw_rad), (x, y, z)))


# primitives ---------------------------------------------------------------------------------------


def box(
    size: Sequence[float],
    center: Sequence[float] = (0, 0, 0),
    material: int = 0,
    bottom: bool = True,
) -> Mesh:
    """Axis-aligned box of size (sx, sy, sz) at center; bottom=False leaves the floor open."""
    sx, sy, sz = (0.5 * float(s) for s in size)
    v = np.array(
        [
            [-sx, -sy, -sz],
            [sx, -sy, -sz],
            [sx, sy, -sz],
            [-sx, sy, -sz],
            [-sx, -sy, sz],
            [sx, -sy, sz],
            [sx, sy, sz],
            [-sx, sy, sz],
        ]
    )
    v = v + np.asarray(center, float)
    t = [
        [4, 5, 6],
        [4, 6, 7],  # top
        [0, 1, 5],
        [0, 5, 4],
        [1, 2, 6],
        [1, 6, 5],
        [2, 3, 7],
        [2, 7, 6],
        [3, 0, 4],
        [3, 4, 7],
    ]
    if bottom:
        t += [[0, 2, 1], [0, 3, 2]]
    return Mesh(v, np.array(t), np.full(len(t), material))


def extrude_profile(profile_xz: np.ndarray, y0: float, y1: float, material: int = 0) -> Mesh:
    """Closed prism from a convex side profile (K, 2) in the x-z plane, extruded from y = y0 to y = y1,
    its faces counter-clockwise seen from outside.
    """
    m = extrude_profile_inward(profile_xz, y0, y1, material)
    return Mesh(m.vertices, m.triangles[:, ::-1], m.material)


def extrude_profile_inward(profile_xz: np.ndarray, y0: float, y1: float, material: int = 0) -> Mesh:
    """`extrude_profile` with every face wound the other way (clockwise seen from outside).

    The T-72, the IFV, the 6x6 truck, the car and the gable roofs were built with this winding; they
    keep it so that their meshes, and every world, template and recording made from them, stay
    byte-identical. The renderer and the LIDAR do not see the difference (first hit, either side); a
    consumer of winding-oriented face normals (the template builder's "faces the view" test) does.
    """
    p = np.asarray(profile_xz, dtype=np.float64)
    k = p.shape[0]
    if _twice_signed_area(p) < 0:  # counter-clockwise in (x, z)
        p = p[::-1]
    v0 = np.column_stack([p[:, 0], np.full(k, y0), p[:, 1]])
    v1 = np.column_stack([p[:, 0], np.full(k, y1), p[:, 1]])
    v = np.vstack([v0, v1])
    t = _prism_triangles(k)
    m = Mesh(v, t, np.full(len(t), material))
    if y1 < y0:
        m = Mesh(v, t[:, ::-1], m.material)
    return m


def loft(
    bottom_xy: np.ndarray, top_xy: np.ndarray, z0: float, z1: float, material: int = 0
) -> Mesh:
    """Closed solid between two convex outlines (K, 2) seen from above: bottom_xy at height z0, top_xy
    at z1 > z0, vertex i of one joined to vertex i of the other (sloped armour, turrets, hulls).
    """
    b = np.asarray(bottom_xy, dtype=np.float64)
    t = np.asarray(top_xy, dtype=np.float64)
    if b.shape != t.shape or b.ndim != 2 or b.shape[1] != 2 or b.shape[0] < 3:
        raise InputError(f"loft outlines must both be (K >= 3, 2), got {b.shape} and {t.shape}")
    if not z1 > z0:
        raise InputError(f"loft top z1 = {z1} m must be above its bottom z0 = {z0} m")
    k = b.shape[0]
    if _twice_signed_area(b) < 0:  # counter-clockwise seen from above, so the faces point outwards
        b, t = b[::-1], t[::-1]
    v = np.vstack([np.column_stack([b, np.full(k, z0)]), np.column_stack([t, np.full(k, z1)])])
    tris = _prism_triangles(k)
    return Mesh(v, tris, np.full(len(tris), material))


def _twice_signed_area(polygon: np.ndarray) -> float:
    """Shoelace sum of a (K, 2) polygon: positive when counter-clockwise."""
    p = polygon
    return float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def _prism_triangles(k: int) -> np.ndarray:
    """(4K - 4, 3) triangles joining ring 0..K-1 to ring K..2K-1 (sides), and a fan over each ring."""
    tris = []
    for i in range(k):
        j = (i + 1) % k
        tris += [[i, j, k + j], [i, k + j, k + i]]
    for i in range(1, k - 1):
        tris += [[0, i + 1, i], [k, k + i, k + i + 1]]
    return np.array(tris)


def cylinder(
    radius: float,
    length: float,
    segments: int = 16,
    material: int = 0,
    axis: str = "z",
    center: Sequence[float] = (0, 0, 0),
    radius_end: float | None = None,
) -> Mesh:
    """Closed cylinder (or frustum when radius_end is given) along axis x, y or z, centred at center."""
    r1 = float(radius) if radius_end is None else float(radius_end)
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring0 = np.column_stack(
        [radius * np.cos(a), radius * np.sin(a), np.full(segments, -0.5 * length)]
    )
    ring1 = np.column_stack([r1 * np.cos(a), r1 * np.sin(a), np.full(segments, 0.5 * length)])
    v = np.vstack([ring0, ring1, [[0, 0, -0.5 * length], [0, 0, 0.5 * length]]])
    tris = []
    n = segments
    for i in range(n):
        j = (i + 1) % n
        tris += [[i, j, n + j], [i, n + j, n + i], [2 * n, j, i], [2 * n + 1, n + i, n + j]]
    if axis == "x":
        v = v[:, [2, 0, 1]]
    elif axis == "y":
        v = v[:, [1, 2, 0]]
    elif axis != "z":
        raise InputError(f"cylinder axis {axis!r} must be 'x', 'y' or 'z'")
    return Mesh(v + np.asarray(center, float), np.array(tris), np.full(len(tris), material))


def ellipsoid(
    radii: Sequence[float],
    center: Sequence[float] = (0, 0, 0),
    material: int = 0,
    rings: int = 8,
    segments: int = 12,
    z_min_frac: float = -1.0,
    power: float = 1.0,
) -> Mesh:
    """Ellipsoid (or a cap of it when z_min_frac > -1); power < 1 flattens the top into a dome."""
    rx, ry, rz = (float(r) for r in radii)
    phis = np.linspace(np.pi / 2, np.arcsin(np.clip(z_min_frac, -1, 1)), rings + 1)
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    verts = [[0.0, 0.0, rz]]
    for phi in phis[1:]:
        c = np.cos(phi)
        s = np.sign(np.sin(phi)) * abs(np.sin(phi)) ** power
        verts += [[rx * c * np.cos(x), ry * c * np.sin(x), rz * s] for x in a]
    v = np.array(verts)
    tris = [[0, 1 + i, 1 + (i + 1) % segments] for i in range(segments)]
    for r in range(rings - 1):
        b0, b1 = 1 + r * segments, 1 + (r + 1) * segments
        for i in range(segments):
            j = (i + 1) % segments
            tris += [[b0 + i, b1 + i, b1 + j], [b0 + i, b1 + j, b0 + j]]
    last = 1 + (rings - 1) * segments
    v = np.vstack([v, [[0.0, 0.0, v[last, 2]]]])
    tris += [[len(v) - 1, last + (i + 1) % segments, last + i] for i in range(segments)]
    return Mesh(v + np.asarray(center, float), np.array(tris), np.full(len(tris), material))


def octahedron(radius: float, center: Sequence[float] = (0, 0, 0), material: int = 0) -> Mesh:
    """Regular octahedron (a cheap closed blob: leaf clumps)."""
    v = radius * np.array(
        [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float
    )
    t = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return Mesh(v + np.asarray(center, float), np.array(t), np.full(8, material))


def gable_roof(
    length: float, width: float, height: float, center: Sequence[float], material: int = 0
) -> Mesh:
    """Gable roof prism along x: base length x width at center z, ridge height above it."""
    lx, wy = 0.5 * length, 0.5 * width
    prof = np.array([[-wy, 0.0], [wy, 0.0], [0.0, height]])
    m = extrude_profile_inward(prof, -lx, lx, material)  # profile in (y, z) extruded along x
    v = m.vertices[:, [1, 0, 2]]
    # swapping x and y mirrors the mesh; flipping the winding back keeps the roofs as they were built
    # (wound inward, see extrude_profile_inward)
    return Mesh(v + np.asarray(center, float), m.triangles[:, ::-1], m.material)
