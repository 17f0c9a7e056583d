"""The vehicle family built in code: the T-72 target, the confusers, and any one of them as the target.

`FAMILY` lists every vehicle with its kind and the published size it is modelled on (main battle tanks
with a long and a short gun, tracked and wheeled carriers, a self-propelled howitzer, military trucks, a
pickup, a car); `VEHICLES` maps each name to its builder and `vehicle(name)` builds one.

Frame of every vehicle: origin on the ground under the hull centre, x forward, y left, z up, metres.
Each is a closed mesh. The T-72, IFV, 6x6 truck and car are the models the committed evaluation and
recordings were made with and stay byte-identical, their prisms wound inward (see
`atr.sim.mesh.extrude_profile_inward`); the others are wound outward.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from atr.errors import InputError
from atr.sim import materials as M
from atr.sim.mesh import (
    Mesh,
    box,
    cylinder,
    ellipsoid,
    extrude_profile,
    extrude_profile_inward,
    loft,
    merge,
)


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
    center: tuple[float, float, float],
    r: float,
    width: float,
    hub_mat: int,
    tyre_mat: int,
    segments: int = 16,
) -> Mesh:
    """A wheel along y: tyre cylinder plus a slightly proud hub disc on the outer side (metres)."""
    x, y, z = center
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


def _symmetric(right_half: list[list[float]]) -> np.ndarray:
    """A plan outline symmetric about y = 0, (K, 2) x, y metres, from its right half (y < 0, rear to
    front): the half, then its mirror image front to rear.
    """
    half = np.array(right_half)
    return np.vstack([half, half[::-1] * np.array([1.0, -1.0])])


def t72() -> Mesh:
    """The T-72 main battle tank: hull, domed turret, 125 mm gun, road wheels, tracks, skirts, drums.

    Published: 9.53 m long with the gun forward (hull 6.86 m), 3.59 m wide over the side skirts,
    2.23 m high (T-72A). The model: turret roof 2.19 m, gun 2.5 m past the hull front, 9.95 m long
    with the rear fuel drums, 2.44 m high to the AA machine gun; vehicle frame, metres.
    """
    parts: list[Mesh] = []
    # hull between the tracks: lower hull, upper glacis at 68 deg from vertical, flat roof at 1.45 m
    hull_prof = np.array(
        [[-3.30, 0.47], [3.00, 0.47], [3.43, 0.95], [2.15, 1.45], [-3.43, 1.45], [-3.43, 0.95]]
    )
    parts.append(extrude_profile_inward(hull_prof, -1.12, 1.12, M.CAMO))
    # sponsons above the tracks, out to the fenders
    spon_prof = np.array([[-3.43, 0.95], [3.43, 0.95], [2.15, 1.45], [-3.43, 1.45]])
    side: list[Mesh] = [extrude_profile_inward(spon_prof, 1.12, 1.62, M.CAMO)]
    # fender shelf and rubber side skirt hiding the upper half of the running gear
    side.append(box((6.7, 0.12, 0.04), (0.0, 1.68, 0.95), M.CAMO))
    side.append(box((6.2, 0.03, 0.38), (-0.1, 1.78, 0.78), M.CAMO))
    # track: bottom and top runs, wrapped around the front idler and rear sprocket
    side.append(box((5.4, 0.58, 0.08), (-0.05, 1.41, 0.04), M.METAL))
    side.append(box((5.9, 0.58, 0.07), (-0.05, 1.41, 0.86), M.METAL))
    wrap_f = _convex_hull_2d(np.vstack([_circle(2.85, 0.47, 0.40), [[2.55, 0.0], [2.6, 0.89]]]))
    wrap_r = _convex_hull_2d(np.vstack([_circle(-3.0, 0.50, 0.40), [[-2.7, 0.0], [-2.8, 0.89]]]))
    side.append(extrude_profile_inward(wrap_f, 1.12, 1.70, M.METAL))
    side.append(extrude_profile_inward(wrap_r, 1.12, 1.70, M.METAL))
    # six road wheels per side, 0.75 m diameter
    for x in (-2.12, -1.28, -0.44, 0.40, 1.24, 2.08):
        side.append(_wheel((x, 1.42, 0.44), 0.375, 0.46, M.METAL, M.RUBBER))
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
    """An infantry fighting vehicle (BMP-2-like): wedge nose, small turret with a 30 mm cannon.

    Published: 6.735 m long, 3.15 m wide, 2.45 m high (BMP-2).
    """
    parts: list[Mesh] = []
    prof = np.array([[-3.36, 0.42], [2.75, 0.42], [3.36, 0.80], [1.35, 1.78], [-3.36, 1.78]])
    parts.append(extrude_profile_inward(prof, -1.02, 1.02, paint))
    side: list[Mesh] = [
        extrude_profile_inward(
            np.array([[-3.36, 0.80], [3.30, 0.80], [1.35, 1.78], [-3.36, 1.78]]), 1.02, 1.50, paint
        )
    ]
    side.append(box((5.2, 0.48, 0.07), (-0.1, 1.26, 0.035), M.METAL))
    side.append(box((5.6, 0.48, 0.06), (-0.1, 1.26, 0.72), M.METAL))
    for x in (-2.3, -1.45, -0.6, 0.25, 1.1, 1.95):
        side.append(_wheel((x, 1.27, 0.36), 0.31, 0.42, M.METAL, M.RUBBER))
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
    """A 6x6 military truck (Ural-4320-like): bonneted cab, canvas-covered bed, three axles.

    Published: 7.366 m long, 2.5 m wide, 2.87 m high (Ural-4320).
    """
    parts: list[Mesh] = []
    parts.append(box((7.2, 1.0, 0.3), (-0.1, 0.0, 0.95), M.METAL))
    hood = np.array([[2.3, 1.05], [3.65, 1.05], [3.65, 1.65], [3.3, 1.95], [2.3, 1.98]])
    parts.append(extrude_profile_inward(hood, -0.85, 0.85, paint))
    parts.append(box((0.08, 1.7, 0.5), (3.69, 0.0, 1.35), M.METAL))  # grille
    cab = np.array([[1.05, 1.05], [2.3, 1.05], [2.3, 2.0], [2.05, 2.62], [1.05, 2.62]])
    parts.append(extrude_profile_inward(cab, -1.2, 1.2, paint))
    parts.append(box((0.04, 2.0, 0.5), (2.19, 0.0, 2.3), M.GLASS))
    for y in (-1.21, 1.21):
        parts.append(box((0.7, 0.02, 0.45), (1.6, y, 2.25), M.GLASS))
    parts.append(box((4.7, 2.5, 0.12), (-1.3, 0.0, 1.36), paint))  # bed floor
    for y in (-1.22, 1.22):
        parts.append(box((4.7, 0.06, 0.45), (-1.3, y, 1.64), paint))
    cover = np.array(
        [[-3.65, 1.8], [1.0, 1.8], [1.0, 2.6], [0.8, 2.88], [-3.45, 2.88], [-3.65, 2.6]]
    )
    parts.append(extrude_profile_inward(cover, -1.2, 1.2, M.CANVAS))
    for x in (2.95, -0.85, -2.35):
        for y in (-1.0, 1.0):
            parts.append(_wheel((x, y, 0.54), 0.54, 0.42, paint, M.RUBBER))
    for x in (2.95, -1.6):
        for y in (-1.0, 1.0):
            parts.append(box((1.4 if x < 0 else 1.2, 0.5, 0.05), (x, y, 1.18), paint))
    return merge(parts)


def car(paint: int = M.PAINT_SILVER) -> Mesh:
    """A family sedan, 4.5 x 1.8 x 1.45 m, in the given paint material.

    Published for a sedan of this class: 4.62 m long, 1.775 m wide, 1.455 m high (Toyota Corolla E170).
    """
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
    parts.append(extrude_profile_inward(_convex_hull_2d(body), -0.88, 0.88, paint))
    cabin = np.array([[1.15, 0.92], [0.35, 1.42], [-1.05, 1.42], [-1.9, 0.97]])
    parts.append(extrude_profile_inward(cabin, -0.76, 0.76, M.GLASS))
    parts.append(box((1.3, 1.5, 0.03), (-0.35, 0.0, 1.435), paint))
    for x in (1.35, -1.35):
        for y in (-0.78, 0.78):
            parts.append(_wheel((x, y, 0.31), 0.31, 0.2, M.PAINT_SILVER, M.RUBBER, 12))
    parts.append(box((0.05, 1.6, 0.15), (2.24, 0.0, 0.5), M.METAL))
    return merge(parts)


# the rest of the family ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Tracks:
    """One side's tracked running gear (left side, mirrored for the right), metres.

    Attributes:
        y: track centre line; width: track width.
        wheel_x: road wheel centres along x; wheel_r: road wheel radius (they touch the track's
            bottom run).
        front, rear: (x, z, r) of the front and rear idler or drive sprocket.
        top_z: height of the top run's centre.

    """

    y: float
    width: float
    wheel_x: tuple[float, ...]
    wheel_r: float
    front: tuple[float, float, float]
    rear: tuple[float, float, float]
    top_z: float


def _tracked_side(tracks: _Tracks) -> Mesh:
    """Bottom and top runs of the track wrapped around idler and sprocket, and the road wheels."""
    y, w = tracks.y, tracks.width
    (fx, fz, fr), (rx, rz, rr) = tracks.front, tracks.rear
    parts = [
        box((fx - rx - 0.3 * (fr + rr), w, 0.08), (0.5 * (fx + rx), y, 0.04), M.METAL),
        box((fx - rx, w, 0.07), (0.5 * (fx + rx), y, tracks.top_z), M.METAL),
    ]
    for x, z, r, inward in ((fx, fz, fr, -1.0), (rx, rz, rr, 1.0)):
        ends = [[x + inward * 0.75 * r, 0.0], [x + inward * 0.6 * r, tracks.top_z + 0.035]]
        wrap = _convex_hull_2d(np.vstack([_circle(x, z, r + 0.04), ends]))
        parts.append(extrude_profile(wrap, y - 0.5 * w, y + 0.5 * w, M.METAL))
    for x in tracks.wheel_x:
        wheel = (x, y, tracks.wheel_r + 0.08)
        parts.append(_wheel(wheel, tracks.wheel_r, 0.8 * w, M.METAL, M.RUBBER))
    return merge(parts)


def _tracked_hull(
    hull_xz: list[list[float]],
    sponson_xz: list[list[float]],
    y_hull: float,
    y_sponson: float,
    tracks: _Tracks,
    paint: int,
    skirts: tuple[Mesh, ...] = (),
) -> tuple[Mesh, list[Mesh]]:
    """A tracked vehicle's hull and the start of its left side, metres.

    The hull is its side profile (x, z) extruded across y = -y_hull..y_hull. The left side holds the
    sponson, its profile extruded from y_hull out to y_sponson, then the skirts and the running gear;
    the caller adds what else stands on that side and mirrors it (`_both_sides`).
    """
    hull = extrude_profile(np.array(hull_xz), -y_hull, y_hull, paint)
    sponson = extrude_profile(np.array(sponson_xz), y_hull, y_sponson, paint)
    return hull, [sponson, *skirts, _tracked_side(tracks)]


def leopard2(paint: int = M.CAMO) -> Mesh:
    """A Leopard-2A6-like main battle tank: long hull, wedge-armoured turret, long 120 mm L/55 gun.

    Published: 10.97 m long with the gun forward (hull 7.72 m), 3.75 m wide over the skirts, 3.0 m
    high to the top of the commander's sight (Leopard 2A6). The model: hull roof 1.6 m, turret roof
    2.55 m, muzzle 3.25 m past the hull front, seven road wheels a side.
    """
    wheels = tuple(-2.7 + 0.9 * k for k in range(7))
    hull, side = _tracked_hull(
        [[-3.86, 0.62], [-3.55, 0.50], [3.25, 0.50], [3.86, 1.05], [2.40, 1.60], [-3.86, 1.60]],
        [[-3.86, 1.02], [3.80, 1.02], [2.40, 1.60], [-3.86, 1.60]],
        1.20,
        1.87,
        _Tracks(1.52, 0.635, wheels, 0.35, (3.3, 0.58, 0.33), (-3.45, 0.62, 0.33), 0.96),
        paint,
        skirts=(
            box((7.3, 0.06, 0.62), (0.05, 1.845, 0.83), paint),  # side skirt
            box((1.4, 0.10, 0.66), (2.95, 1.825, 0.83), paint),  # heavier front skirt
        ),
    )
    parts = [hull]
    side.append(box((1.6, 0.25, 0.5), (-1.3, 1.62, 2.05), paint))  # turret stowage box
    side.append(box((0.35, 0.3, 0.25), (-2.2, 1.55, 2.2), M.METAL))  # smoke dischargers
    parts.append(_both_sides(merge(side)))
    parts.append(box((2.2, 2.0, 0.04), (-2.6, 0.0, 1.62), M.METAL))  # engine deck grille
    parts.append(box((0.05, 2.0, 0.5), (-3.885, 0.0, 1.2), M.METAL))  # rear exhaust grille
    # turret: arrow-shaped wedge armour at the front, long bustle, sides leaning in
    bottom = _symmetric([[-2.85, -1.50], [0.95, -1.62], [2.05, -0.42]])
    top = _symmetric([[-2.75, -1.38], [0.85, -1.50], [1.75, -0.40]])
    parts.append(loft(bottom, top, 1.60, 2.55, paint))
    parts.append(box((0.5, 2.4, 0.45), (-3.05, 0.0, 2.12), M.METAL))  # bustle basket
    # commander's panoramic sight (to 3.0 m), gunner's sight, loader's hatch
    parts.append(cylinder(0.20, 0.45, 14, paint, center=(-0.55, -0.75, 2.775)))
    parts.append(box((0.7, 0.5, 0.30), (0.55, -0.85, 2.70), paint))
    parts.append(cylinder(0.33, 0.06, 14, paint, center=(-0.55, 0.70, 2.58)))
    # 120 mm L/55 gun: mantlet, thermal sleeve, bore evacuator, muzzle at 7.11 m
    parts.append(box((0.55, 0.75, 0.65), (2.05, 0.0, 2.10), paint))
    parts.append(cylinder(0.115, 2.15, 12, M.METAL, axis="x", center=(3.375, 0.0, 2.10)))
    parts.append(cylinder(0.16, 0.60, 12, M.METAL, axis="x", center=(4.75, 0.0, 2.10)))
    parts.append(cylinder(0.095, 2.06, 12, M.METAL, axis="x", center=(6.08, 0.0, 2.10)))
    return merge(parts)


def m1(paint: int = M.SAND) -> Mesh:
    """An M1A1-Abrams-like main battle tank: low flat angular turret, shorter 120 mm L/44 gun.

    Published: 9.77 m long with the gun forward (hull 7.92 m), 3.66 m wide, 2.44 m high over the
    turret hatch (M1A1). The model: hull roof 1.44 m, turret roof 2.36 m, muzzle 1.85 m past the hull
    front, deep skirts over seven road wheels a side, bustle rack.
    """
    wheels = tuple(-2.85 + 0.95 * k for k in range(7))
    hull, side = _tracked_hull(
        [[-3.96, 0.60], [-3.70, 0.48], [3.30, 0.48], [3.96, 0.98], [2.35, 1.44], [-3.96, 1.44]],
        [[-3.96, 0.98], [3.85, 0.98], [2.35, 1.44], [-3.96, 1.44]],
        1.16,
        1.83,
        _Tracks(1.49, 0.635, wheels, 0.32, (3.45, 0.55, 0.32), (-3.55, 0.62, 0.32), 0.90),
        paint,
        skirts=(
            box((7.0, 0.06, 0.70), (0.15, 1.80, 0.80), paint),  # side skirt
            box((1.5, 0.10, 0.72), (3.0, 1.78, 0.80), paint),  # heavier front skirt
        ),
    )
    parts = [hull]
    side.append(box((0.3, 0.35, 0.22), (1.1, 1.55, 2.05), M.METAL))  # smoke grenade launchers
    side.append(box((1.8, 0.2, 0.4), (-1.6, 1.38, 1.95), paint))  # turret side stowage
    parts.append(_both_sides(merge(side)))
    parts.append(box((0.05, 2.1, 0.6), (-3.985, 0.0, 1.1), M.METAL))  # rear grille door
    parts.append(box((1.8, 2.0, 0.04), (-2.9, 0.0, 1.46), M.METAL))  # engine deck
    # flat-faced turret: cheeks swept back from the gun, long bustle, sides leaning in
    bottom = _symmetric([[-3.25, -1.30], [0.55, -1.75], [1.75, -0.55]])
    top = _symmetric([[-3.15, -1.20], [0.45, -1.60], [1.45, -0.50]])
    parts.append(loft(bottom, top, 1.44, 2.36, paint))
    parts.append(box((0.75, 2.5, 0.40), (-3.55, 0.0, 2.0), M.METAL))  # bustle rack
    # commander's cupola with the .50 cal, loader's hatch, gunner's primary sight
    parts.append(cylinder(0.42, 0.14, 16, paint, center=(-0.55, -0.72, 2.43)))
    parts.append(cylinder(0.03, 1.1, 6, M.METAL, axis="x", center=(-0.1, -0.72, 2.52)))
    parts.append(cylinder(0.35, 0.06, 14, paint, center=(-0.5, 0.72, 2.39)))
    parts.append(box((0.55, 0.45, 0.16), (0.85, -0.95, 2.44), paint))
    # 120 mm L/44 gun: mantlet, thermal sleeve, bore evacuator, muzzle at 5.81 m
    parts.append(box((0.45, 0.95, 0.55), (1.75, 0.0, 1.95), paint))
    parts.append(cylinder(0.11, 1.9, 12, M.METAL, axis="x", center=(2.9, 0.0, 1.95)))
    parts.append(cylinder(0.15, 0.5, 12, M.METAL, axis="x", center=(4.1, 0.0, 1.95)))
    parts.append(cylinder(0.095, 1.46, 12, M.METAL, axis="x", center=(5.08, 0.0, 1.95)))
    return merge(parts)


def m113(paint: int = M.OLIVE) -> Mesh:
    """An M113-like tracked armoured personnel carrier: a tall box with a sloped glacis, no turret.

    Published: 4.86 m long, 2.69 m wide, 2.50 m high over the commander's machine gun (M113). The
    model: hull roof 1.83 m, five road wheels a side, trim vane, rear ramp, cupola with a shielded
    12.7 mm machine gun.
    """
    wheels = (-1.62, -0.81, 0.0, 0.81, 1.62)
    hull, side = _tracked_hull(
        [[-2.43, 0.42], [1.95, 0.42], [2.43, 1.0], [1.65, 1.83], [-2.43, 1.83]],
        [[-2.43, 0.95], [2.38, 0.95], [1.65, 1.83], [-2.43, 1.83]],  # the upper hull's sides
        0.96,
        1.34,
        _Tracks(1.15, 0.38, wheels, 0.23, (2.05, 0.62, 0.26), (-2.15, 0.52, 0.26), 0.86),
        paint,
    )
    parts = [hull]
    side.append(box((0.5, 0.08, 0.3), (1.7, 1.30, 1.35), M.METAL))  # exhaust / lights guard
    parts.append(_both_sides(merge(side)))
    vane = np.array([[2.44, 1.03], [2.48, 1.03], [1.95, 1.64], [1.91, 1.64]])
    parts.append(extrude_profile(vane, -0.9, 0.9, paint))  # trim vane, proud of the glacis
    parts.append(box((0.04, 1.7, 1.2), (-2.45, 0.0, 1.05), paint))  # rear ramp
    parts.append(box((1.3, 1.2, 0.04), (-1.2, 0.0, 1.85), paint))  # cargo hatch
    parts.append(cylinder(0.30, 0.08, 12, paint, center=(1.3, 0.55, 1.87)))  # driver's hatch
    # commander's cupola, gun shield, 12.7 mm machine gun
    parts.append(cylinder(0.42, 0.25, 16, paint, center=(0.5, -0.3, 1.955)))
    parts.append(box((0.06, 0.75, 0.42), (0.95, -0.3, 2.29), paint))
    parts.append(cylinder(0.03, 1.4, 6, M.METAL, axis="x", center=(1.4, -0.3, 2.2)))
    return merge(parts)


def btr80(paint: int = M.OLIVE) -> Mesh:
    """A BTR-80-like 8x8 wheeled armoured personnel carrier: boat hull, small 14.5 mm turret.

    Published: 7.7 m long, 2.9 m wide, 2.41 m high (BTR-80). The model: lower hull flaring out to a
    chine at 1.3 m, upper hull leaning in to a roof at 2.02 m, a conical turret, eight 1.12 m wheels
    on axles 1.35, 1.525 and 1.35 m apart, 2.41 m track.
    """
    parts: list[Mesh] = []
    # boat-hull octagons; np.roll starts each on its right side, the stern pair of corners last
    keel, chine, roof = (
        np.roll(_symmetric(half), -1, axis=0)
        for half in (
            [[-3.5, -0.35], [-3.2, -0.75], [2.8, -0.75], [3.3, -0.35]],
            [[-3.85, -0.7], [-3.65, -1.45], [3.25, -1.45], [3.85, -0.6]],
            [[-3.6, -0.55], [-3.45, -1.1], [1.75, -1.1], [2.3, -0.55]],
        )
    )
    parts.append(loft(keel, chine, 0.475, 1.30, paint))
    parts.append(loft(chine, roof, 1.30, 2.02, paint))
    for x in (2.1125, 0.7625, -0.7625, -2.1125):
        for y in (-1.205, 1.205):
            parts.append(_wheel((x, y, 0.56), 0.56, 0.33, M.METAL, M.RUBBER))
    # turret with the 14.5 mm machine gun, roof hatches, engine grille, headlights
    parts.append(cylinder(0.62, 0.39, 14, paint, center=(0.85, 0.0, 2.215), radius_end=0.50))
    parts.append(cylinder(0.05, 1.6, 8, M.METAL, axis="x", center=(2.15, 0.0, 2.25)))
    for x, y in ((1.9, 0.45), (1.9, -0.45), (-0.6, 0.5), (-0.6, -0.5)):
        parts.append(cylinder(0.25, 0.05, 10, paint, center=(x, y, 2.045)))
    parts.append(box((1.4, 1.6, 0.04), (-2.6, 0.0, 2.04), M.METAL))
    for y in (-0.9, 0.9):
        parts.append(box((0.12, 0.25, 0.18), (3.22, y, 1.45), M.METAL))
    return merge(parts)


def m109(paint: int = M.CAMO) -> Mesh:
    """An M109A6-like self-propelled howitzer: large box turret on the rear, long 155 mm gun.

    Published: 9.8 m long with the gun forward, 3.15 m wide, 3.24 m high (M109A6 Paladin; Gary's
    Combat Vehicle Reference Guide). The model: hull 6.19 m, turret roof 3.05 m with a rear bustle,
    gun in its travel lock over the glacis with bore evacuator and muzzle brake, seven road wheels.
    """
    wheels = tuple(-2.34 + 0.78 * k for k in range(7))
    hull, side = _tracked_hull(
        [[-3.095, 0.46], [2.55, 0.46], [3.095, 1.05], [2.30, 1.55], [-3.095, 1.55]],
        [[-3.095, 1.0], [3.0, 1.0], [2.30, 1.55], [-3.095, 1.55]],
        1.19,
        1.575,
        _Tracks(1.385, 0.38, wheels, 0.24, (2.75, 0.62, 0.29), (-2.85, 0.55, 0.29), 0.93),
        paint,
    )
    parts = [hull]
    side.append(box((1.8, 0.07, 0.45), (-1.2, 1.535, 2.2), paint))  # turret side stowage
    parts.append(_both_sides(merge(side)))
    bottom = _symmetric([[-3.05, -1.5], [0.9, -1.5], [1.3, -1.2]])
    top = _symmetric([[-2.95, -1.38], [0.75, -1.38], [1.05, -1.1]])
    parts.append(loft(bottom, top, 1.55, 3.05, paint))
    parts.append(box((0.6, 2.6, 0.9), (-3.3, 0.0, 2.45), paint))  # rear bustle
    # commander's cupola and machine gun (to 3.24 m)
    parts.append(cylinder(0.45, 0.12, 16, paint, center=(-0.2, 0.85, 3.11)))
    parts.append(cylinder(0.035, 1.2, 6, M.METAL, axis="x", center=(0.2, 0.85, 3.20)))
    # 155 mm gun: mantlet, barrel, bore evacuator, muzzle brake at 6.2 m; travel lock on the glacis
    parts.append(box((0.5, 0.9, 0.7), (1.45, 0.0, 2.35), paint))
    parts.append(cylinder(0.13, 3.95, 12, M.METAL, axis="x", center=(3.675, 0.0, 2.35)))
    parts.append(cylinder(0.20, 0.9, 12, M.METAL, axis="x", center=(3.2, 0.0, 2.35)))
    parts.append(box((0.55, 0.42, 0.36), (5.925, 0.0, 2.35), M.METAL))
    parts.append(box((0.12, 0.45, 0.75), (2.65, 0.0, 1.75), M.METAL))
    return merge(parts)


def hmmwv(paint: int = M.SAND) -> Mesh:
    """An M998-HMMWV-like 4x4 light utility vehicle: wide and low, bonnet, cab, soft-top rear.

    Published: 4.57 m long, 2.16 m wide, 1.83 m high (M998 HMMWV). The model: 3.30 m wheelbase,
    1.82 m track, 0.94 m tyres, fenders over the wheels, canvas over the rear body.
    """
    parts: list[Mesh] = []
    parts.append(box((4.50, 1.60, 0.50), (0.0, 0.0, 0.80), paint))  # body between the wheels
    side = [box((1.9, 0.28, 0.55), (0.0, 0.94, 0.775), paint)]  # side panel between the wheels
    for x in (1.65, -1.65):
        side.append(box((1.2, 0.30, 0.08), (x, 0.93, 1.01), paint))  # fender over the wheel
        side.append(_wheel((x, 0.91, 0.47), 0.47, 0.32, M.METAL, M.RUBBER))
    side.append(box((0.9, 0.02, 0.35), (-0.1, 0.99, 1.58), M.GLASS))  # side window
    parts.append(_both_sides(merge(side)))
    hood = np.array([[0.8, 1.05], [2.28, 1.05], [2.20, 1.22], [0.8, 1.40]])
    parts.append(extrude_profile(hood, -1.08, 1.08, paint))
    cab = np.array([[-0.95, 1.05], [0.8, 1.05], [0.8, 1.40], [0.55, 1.83], [-0.95, 1.83]])
    parts.append(extrude_profile(cab, -0.98, 0.98, paint))
    screen = np.array([[0.81, 1.42], [0.84, 1.42], [0.60, 1.80], [0.57, 1.80]])
    parts.append(extrude_profile(screen, -0.9, 0.9, M.GLASS))
    cover = np.array([[-2.28, 1.05], [-0.95, 1.05], [-0.95, 1.80], [-2.28, 1.70]])
    parts.append(extrude_profile(cover, -0.98, 0.98, M.CANVAS))
    parts.append(box((0.08, 1.7, 0.3), (2.28, 0.0, 0.85), M.METAL))  # grille
    parts.append(box((0.12, 2.0, 0.12), (2.22, 0.0, 0.60), M.METAL))  # bumper
    return merge(parts)


def pickup(paint: int = M.PAINT_WHITE) -> Mesh:
    """A Toyota-Hilux-like double-cab pickup: bonnet, four-door cab, open load bed.

    Published: 5.33 m long, 1.855 m wide (without mirrors), 1.815 m high (Hilux double cab, 2016).
    The model: 3.085 m wheelbase, 1.54 m track, 0.77 m tyres, glass all round the cab.
    """
    parts: list[Mesh] = []
    nose = np.array(
        [[0.9, 0.45], [2.50, 0.45], [2.665, 0.70], [2.60, 1.00], [1.0, 1.12], [0.9, 1.12]]
    )
    parts.append(extrude_profile(nose, -0.9275, 0.9275, paint))
    parts.append(box((1.85, 1.855, 0.67), (-0.025, 0.0, 0.785), paint))  # cab body
    glass = np.array([[-0.95, 1.12], [0.9, 1.12], [0.15, 1.74], [-0.85, 1.77]])
    parts.append(extrude_profile(glass, -0.80, 0.80, M.GLASS))
    parts.append(box((0.95, 1.5, 0.04), (-0.35, 0.0, 1.795), paint))  # roof
    # load bed: a box below the floor, walls and tailgate above it
    parts.append(box((1.70, 1.855, 0.30), (-1.815, 0.0, 0.65), paint))
    for y in (-0.8975, 0.8975):
        parts.append(box((1.70, 0.06, 0.32), (-1.815, y, 0.96), paint))
    for x in (-2.635, -0.995):
        parts.append(box((0.06, 1.735, 0.32), (x, 0.0, 0.96), paint))
    for x in (1.54, -1.545):
        for y in (-0.77, 0.77):
            parts.append(_wheel((x, y, 0.385), 0.385, 0.265, M.PAINT_SILVER, M.RUBBER, 14))
    parts.append(box((0.1, 1.7, 0.2), (2.62, 0.0, 0.55), M.METAL))  # bumper
    parts.append(box((0.1, 1.6, 0.15), (-2.62, 0.0, 0.45), M.METAL))  # rear bumper
    return merge(parts)


@dataclass(frozen=True)
class VehicleSpec:
    """A vehicle of the family: its builder and the published size it is modelled on.

    Attributes:
        name: registry name (the target or confuser name in truth and templates).
        kind: what sort of vehicle it is.
        build: builds the mesh in the vehicle frame (metres).
        size_m: published overall length (gun forward), width, height, metres.
        source: the vehicle the size was published for, and where.

    """

    name: str
    kind: str
    build: Callable[[], Mesh]
    size_m: tuple[float, float, float]
    source: str


FAMILY: tuple[VehicleSpec, ...] = (
    VehicleSpec(
        name="t72",
        kind="main battle tank",
        build=t72,
        size_m=(9.53, 3.59, 2.23),
        source="T-72A (Wikipedia, T-72)",
    ),
    VehicleSpec(
        name="ifv",
        kind="tracked infantry fighting vehicle",
        build=ifv,
        size_m=(6.735, 3.15, 2.45),
        source="BMP-2 (Wikipedia)",
    ),
    VehicleSpec(
        name="truck6x6",
        kind="military truck 6x6",
        build=truck_6x6,
        size_m=(7.366, 2.5, 2.87),
        source="Ural-4320 (Wikipedia)",
    ),
    VehicleSpec(
        name="car",
        kind="car (sedan)",
        build=car,
        size_m=(4.62, 1.775, 1.455),
        source="Toyota Corolla E170 sedan",
    ),
    VehicleSpec(
        name="leopard2",
        kind="main battle tank, long gun",
        build=leopard2,
        size_m=(10.97, 3.75, 3.0),
        source="Leopard 2A6 (Wikipedia)",
    ),
    VehicleSpec(
        name="m1",
        kind="main battle tank, low turret, short gun",
        build=m1,
        size_m=(9.77, 3.66, 2.44),
        source="M1A1 Abrams (Wikipedia)",
    ),
    VehicleSpec(
        name="m113",
        kind="tracked armoured personnel carrier",
        build=m113,
        size_m=(4.863, 2.686, 2.5),
        source="M113 (Wikipedia)",
    ),
    VehicleSpec(
        name="btr80",
        kind="wheeled armoured personnel carrier 8x8",
        build=btr80,
        size_m=(7.7, 2.9, 2.41),
        source="BTR-80 (Wikipedia)",
    ),
    VehicleSpec(
        name="m109",
        kind="self-propelled howitzer",
        build=m109,
        size_m=(9.8, 3.15, 3.24),
        source="M109A6 Paladin (Gary's Combat Vehicle Reference Guide)",
    ),
    VehicleSpec(
        name="hmmwv",
        kind="light utility vehicle 4x4",
        build=hmmwv,
        size_m=(4.57, 2.16, 1.83),
        source="M998 HMMWV (Wikipedia)",
    ),
    VehicleSpec(
        name="pickup",
        kind="pickup truck (double cab)",
        build=pickup,
        size_m=(5.33, 1.855, 1.815),
        source="Toyota Hilux double cab (2016, Toyota)",
    ),
)
"""Every vehicle built in code, the T-72 first; any of them can be the target, any others confusers."""

VEHICLES: dict[str, Callable[[], Mesh]] = {spec.name: spec.build for spec in FAMILY}
"""Name -> builder of every vehicle of `FAMILY`."""


def vehicle(name: str) -> Mesh:
    """The vehicle of `VEHICLES` called name, built in its vehicle frame.

    Raises:
        InputError: no vehicle has that name (the message lists the known names).

    """
    if name not in VEHICLES:
        raise InputError(f"unknown vehicle {name!r}; known vehicles: {', '.join(VEHICLES)}")
    return VEHICLES[name]()
