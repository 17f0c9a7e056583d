"""Vehicle meshes built in code: the T-72 target and the confusers (IFV, 6x6 truck, cars).

Frame of every vehicle: origin on the ground under the hull centre, x forward, y left, z up, metres.
Proportions follow published dimensions (T-72: hull 6.86 m long, 3.59 m wide over the side skirts,
2.19 m to the turret roof, 125 mm gun overhanging the hull front by ~2.5 m; BMP-2-like IFV 6.7 x
3.15 x 2.45 m; Ural-4320-like 6x6 truck 7.4 x 2.5 x 2.9 m; a family sedan 4.5 x 1.8 x 1.45 m).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from atr.sim import materials as M
from atr.sim.mesh import Mesh, box, cylinder, ellipsoid, extrude_profile, merge


def _convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of (K, 2) points (monotone chain)."""
    pts = sorted(map(tuple, np.round(points, 9)))

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _circle(cx: float, cz: float, r: float, n: int = 12) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([cx + r * np.cos(a), cz + r * np.sin(a)])


def _wheel(
    x: float,
    y: float,
    z: float,
    r: float,
    width: float,
    hub_mat: int,
    tyre_mat: int,
    segments: int = 16,
) -> Mesh:
    """A wheel along y: tyre cylinder plus a slightly proud hub disc on the outer side."""
    side = np.sign(y) if y != 0 else 1.0
    tyre = cylinder(r, width, segments, tyre_mat, axis="y", center=(x, y, z))
    hub_y = y + side * (0.5 * width + 0.01)
    hub = cylinder(0.55 * r, 0.02, segments, hub_mat, axis="y", center=(x, hub_y, z))
    return merge([tyre, hub])


def _mirror_y(mesh: Mesh) -> Mesh:
    v = mesh.vertices * np.array([1.0, -1.0, 1.0])
    return Mesh(v, mesh.triangles[:, ::-1], mesh.material)


def _both_sides(mesh: Mesh) -> Mesh:
    return merge([mesh, _mirror_y(mesh)])


def t72() -> Mesh:
    """The T-72 main battle tank: hull, domed turret, 125 mm gun, road wheels, tracks, skirts,
    drums.

    Returns:
        Mesh in the vehicle frame (origin on the ground under the hull centre, x forward), metres.

    """
    parts: list[Mesh] = []
    # hull between the tracks: lower hull, upper glacis at 68 deg from vertical, flat roof at 1.45 m
    hull_prof = np.array(
        [[-3.30, 0.47], [3.00, 0.47], [3.43, 0.95], [2.15, 1.45], [-3.43, 1.45], [-3.43, 0.95]]
    )
    parts.append(extrude_profile(hull_prof, -1.12, 1.12, M.CAMO))
    # sponsons above the tracks, out to the fenders
    spon_prof = np.array([[-3.43, 0.95], [3.43, 0.95], [2.15, 1.45], [-3.43, 1.45]])
    side: list[Mesh] = [extrude_profile(spon_prof, 1.12, 1.62, M.CAMO)]
    # fender shelf and rubber side skirt hiding the upper half of the running gear
    side.append(box((6.7, 0.12, 0.04), (0.0, 1.68, 0.95), M.CAMO))
    side.append(box((6.2, 0.03, 0.38), (-0.1, 1.78, 0.78), M.CAMO))
    # track: bottom and top runs, wrapped around the front idler and rear sprocket
    side.append(box((5.4, 0.58, 0.08), (-0.05, 1.41, 0.04), M.METAL))
    side.append(box((5.9, 0.58, 0.07), (-0.05, 1.41, 0.86), M.METAL))
    wrap_f = _convex_hull_2d(np.vstack([_circle(2.85, 0.47, 0.40), [[2.55, 0.0], [2.6, 0.89]]]))
    wrap_r = _convex_hull_2d(np.vstack([_circle(-3.0, 0.50, 0.40), [[-2.7, 0.0], [-2.8, 0.89]]]))
    side.append(extrude_profile(wrap_f, 1.12, 1.70, M.METAL))
    side.append(extrude_profile(wrap_r, 1.12, 1.70, M.METAL))
    # six road wheels per side, 0.75 m diameter
    for x in (-2.12, -1.28, -0.44, 0.40, 1.24, 2.08):
        side.append(_wheel(x, 1.42, 0.44, 0.375, 0.46, M.METAL, M.RUBBER))
    # stowage boxes and external fuel tanks on the fender
    boxes = ((-2.9, 0.9, 0.38), (-1.8, 1.1, 0.42), (-0.5, 0.8, 0.36), (0.55, 1.0, 0.40))
    for x0, length, h in boxes:
        side.append(box((length, 0.36, h), (x0 + 0.5 * length, 1.50, 0.97 + 0.5 * h), M.CAMO))
    parts.append(_both_sides(merge(side)))
    # engine deck grilles and the driver's hatch on the glacis
    parts.append(box((1.6, 1.6, 0.03), (-2.4, 0.0, 1.465), M.METAL))
    for k in range(7):  # louvres of the engine-deck grille
        parts.append(box((0.1, 1.5, 0.05), (-3.1 + 0.23 * k, 0.0, 1.49), M.CAMO))
    parts.append(box((0.8, 1.0, 0.04), (-1.45, 0.0, 1.47), M.CAMO))
    parts.append(box((0.45, 0.55, 0.1), (2.0, 0.0, 1.48), M.CAMO))
    # domed cast turret, slightly forward of the hull centre
    parts.append(
        ellipsoid(
            (1.55, 1.45, 0.76),
            (0.30, 0.0, 1.44),
            M.CAMO,
            rings=8,
            segments=28,
            z_min_frac=0.0,
            power=0.55,
        )
    )
    # commander's cupola (right), gunner's hatch (left), AA machine gun, IR searchlight, snorkel
    parts.append(cylinder(0.36, 0.16, 16, M.CAMO, center=(-0.15, -0.48, 2.16)))
    parts.append(
        ellipsoid(
            (0.33, 0.33, 0.10), (-0.15, -0.48, 2.24), M.CAMO, rings=3, segments=16, z_min_frac=0.0
        )
    )
    parts.append(cylinder(0.30, 0.08, 14, M.CAMO, center=(-0.05, 0.50, 2.14)))
    parts.append(cylinder(0.025, 1.2, 6, M.METAL, axis="x", center=(0.25, -0.48, 2.42)))
    parts.append(box((0.2, 0.06, 0.18), (-0.25, -0.48, 2.33), M.METAL))
    parts.append(cylinder(0.18, 0.3, 14, M.METAL, axis="x", center=(1.25, -0.62, 2.02)))
    parts.append(box((0.35, 0.25, 0.28), (0.95, 0.62, 2.02), M.CAMO))
    parts.append(cylinder(0.09, 1.6, 10, M.CAMO, axis="y", center=(-1.30, 0.1, 1.88)))
    # 125 mm gun: mantlet, barrel with thermal sleeve and fume extractor, muzzle 2.5 m past the hull
    # front
    parts.append(
        cylinder(0.30, 0.55, 16, M.CAMO, axis="x", center=(1.70, 0.0, 1.80), radius_end=0.20)
    )
    parts.append(cylinder(0.105, 2.6, 12, M.METAL, axis="x", center=(3.25, 0.0, 1.80)))
    parts.append(cylinder(0.15, 0.55, 12, M.METAL, axis="x", center=(4.05, 0.0, 1.80)))
    parts.append(cylinder(0.085, 1.45, 12, M.METAL, axis="x", center=(5.20, 0.0, 1.80)))
    # rear: two 200 l fuel drums across the rear plate and the unditching log above them
    for y in (-0.55, 0.55):
        parts.append(cylinder(0.29, 0.88, 14, M.CAMO, axis="y", center=(-3.74, y, 1.18)))
    parts.append(cylinder(0.12, 3.3, 10, M.BARK, axis="y", center=(-3.55, 0.0, 1.58)))
    return merge(parts)


def ifv(paint: int = M.OLIVE) -> Mesh:
    """An infantry fighting vehicle (BMP-2-like): wedge nose, small turret with a 30 mm cannon."""
    parts: list[Mesh] = []
    prof = np.array([[-3.36, 0.42], [2.75, 0.42], [3.36, 0.80], [1.35, 1.78], [-3.36, 1.78]])
    parts.append(extrude_profile(prof, -1.02, 1.02, paint))
    side: list[Mesh] = [
        extrude_profile(
            np.array([[-3.36, 0.80], [3.30, 0.80], [1.35, 1.78], [-3.36, 1.78]]), 1.02, 1.50, paint
        )
    ]
    side.append(box((5.2, 0.48, 0.07), (-0.1, 1.26, 0.035), M.METAL))
    side.append(box((5.6, 0.48, 0.06), (-0.1, 1.26, 0.72), M.METAL))
    for x in (-2.3, -1.45, -0.6, 0.25, 1.1, 1.95):
        side.append(_wheel(x, 1.27, 0.36, 0.31, 0.42, M.METAL, M.RUBBER))
    side.append(box((6.4, 0.03, 0.3), (0.0, 1.58, 0.66), paint))
    parts.append(_both_sides(merge(side)))
    parts.append(cylinder(0.75, 0.5, 8, paint, center=(0.1, 0.0, 2.03), radius_end=0.55))
    parts.append(cylinder(0.05, 2.9, 8, M.METAL, axis="x", center=(1.9, 0.0, 2.05)))
    parts.append(box((0.5, 0.25, 0.25), (0.3, 0.55, 2.35), M.METAL))
    for x in (-1.6, -2.4):
        for y in (-0.45, 0.45):
            parts.append(box((0.6, 0.5, 0.06), (x, y, 1.81), paint))
    return merge(parts)


def truck_6x6(paint: int = M.OLIVE) -> Mesh:
    """A 6x6 military truck (Ural-4320-like): bonneted cab, canvas-covered bed, three axles."""
    parts: list[Mesh] = []
    parts.append(box((7.2, 1.0, 0.3), (-0.1, 0.0, 0.95), M.METAL))
    hood = np.array([[2.3, 1.05], [3.65, 1.05], [3.65, 1.65], [3.3, 1.95], [2.3, 1.98]])
    parts.append(extrude_profile(hood, -0.85, 0.85, paint))
    parts.append(box((0.08, 1.7, 0.5), (3.69, 0.0, 1.35), M.METAL))  # grille
    cab = np.array([[1.05, 1.05], [2.3, 1.05], [2.3, 2.0], [2.05, 2.62], [1.05, 2.62]])
    parts.append(extrude_profile(cab, -1.2, 1.2, paint))
    parts.append(box((0.04, 2.0, 0.5), (2.19, 0.0, 2.3), M.GLASS))
    for y in (-1.21, 1.21):
        parts.append(box((0.7, 0.02, 0.45), (1.6, y, 2.25), M.GLASS))
    parts.append(box((4.7, 2.5, 0.12), (-1.3, 0.0, 1.36), paint))  # bed floor
    for y in (-1.22, 1.22):
        parts.append(box((4.7, 0.06, 0.45), (-1.3, y, 1.64), paint))
    cover = np.array(
        [[-3.65, 1.8], [1.0, 1.8], [1.0, 2.6], [0.8, 2.88], [-3.45, 2.88], [-3.65, 2.6]]
    )
    parts.append(extrude_profile(cover, -1.2, 1.2, M.CANVAS))
    for x in (2.95, -0.85, -2.35):
        for y in (-1.0, 1.0):
            parts.append(_wheel(x, y, 0.54, 0.54, 0.42, paint, M.RUBBER))
    for x in (2.95, -1.6):
        for y in (-1.0, 1.0):
            parts.append(box((1.4 if x < 0 else 1.2, 0.5, 0.05), (x, y, 1.18), paint))
    return merge(parts)


def car(paint: int = M.PAINT_SILVER) -> Mesh:
    """A family sedan, 4.5 x 1.8 x 1.45 m, in the given paint material."""
    parts: list[Mesh] = []
    body = np.array(
        [
            [-2.25, 0.30],
            [2.1, 0.30],
            [2.25, 0.55],
            [2.2, 0.75],
            [1.15, 0.92],
            [-2.2, 0.98],
            [-2.28, 0.6],
        ]
    )
    parts.append(extrude_profile(_convex_hull_2d(body), -0.88, 0.88, paint))
    cabin = np.array([[1.15, 0.92], [0.35, 1.42], [-1.05, 1.42], [-1.9, 0.97]])
    parts.append(extrude_profile(cabin, -0.76, 0.76, M.GLASS))
    parts.append(box((1.3, 1.5, 0.03), (-0.35, 0.0, 1.435), paint))
    for x in (1.35, -1.35):
        for y in (-0.78, 0.78):
            parts.append(_wheel(x, y, 0.31, 0.31, 0.2, M.PAINT_SILVER, M.RUBBER, 12))
    parts.append(box((0.05, 1.6, 0.15), (2.24, 0.0, 0.5), M.METAL))
    return merge(parts)


VEHICLES: dict[str, Callable[[], Mesh]] = {
    "t72": t72,
    "ifv": ifv,
    "truck6x6": truck_6x6,
    "car": car,
}
