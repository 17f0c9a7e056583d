"""The simulated urban world of a scenario run: terrain, streets, buildings, trees, vehicles.

A seed fixes the city (street grid, lots, buildings, trees, parked cars, confusers, the target's
place and heading, the sun), whichever vehicle the target is. A run then removes what its UAV orbit would fly into, and what could
hide the target completely, except one tall "occluder" building next to the target whose width is
tuned so the share of the run's frames without a visible target matches Table II (see docs/sim.md,
"Scenes without target").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from atr.errors import InputError
from atr.sim import materials as M
from atr.sim.config import SimConfig
from atr.sim.mesh import Mesh, box, cylinder, gable_roof, merge, place, pose, rot_z
from atr.sim.scenarios import Scenario
from atr.sim.trajectory import Orbit, make_orbit
from atr.sim.vehicles import car, ifv, truck_6x6, vehicle

_TERRAIN_HALF_M = 400.0  # half size of the detailed terrain square, metres
# terrain grid spacing, metres (waves are >= 40 m long: < 1 cm interpolation error)
_TERRAIN_STEP_M = 5.0
_HORIZON_HALF_M = 6000.0  # half size of the flat outer ground that fills the view to the horizon
_STREET_SPACING_M = (62.0, 85.0)  # distance between parallel streets, metres
_STREET_WIDTH_M = (8.0, 12.0)  # carriageway width, metres
_SIDEWALK_M = 2.5  # sidewalk width, metres
_CITY_HALF_M = 330.0  # buildings are placed within this half size, metres
_TARGET_TOP_M = 2.2  # a building lower than this above the line of sight cannot hide the target
_CLEAR_AROUND_TARGET_M = 9.0  # no building or tree this close to the target, metres
# horizontal and vertical margin kept between the orbit and any object, metres
_UAV_CLEARANCE_M = 8.0


@dataclass(frozen=True)
class World:
    """A built world ready for rendering.

    Attributes:
        seed: seed the world was built from.
        static: every surface except the target (terrain, buildings, trees, vehicles), world frame.
        target: the target mesh in the world frame.
        target_name: name of the target ("t72", another vehicle of the family, or the name given
            for a custom mesh).
        T_world_target: (4, 4) world-from-target pose (target frame: origin on the ground, x
            forward).
        target_local: the target mesh in its own frame.
        ground_rects: (K, 8) float64 ground map rectangles (cx, cy, half_u, half_v, cos, sin,
            material, centre-line marking flag), last match wins.
        sun_dir: (3,) unit vector from the ground towards the sun.
        orbit: the run's camera-head trajectory.
        occluder_width_m: width of the tuned occluder building (0 when the run needs none).
        vehicles: every vehicle of ``static``, parked cars and confusers, where it stands (the truth that
            tells which non-target object a false detection sits on).

    """

    seed: int
    static: Mesh
    target: Mesh
    target_name: str
    T_world_target: np.ndarray
    target_local: Mesh
    ground_rects: np.ndarray
    sun_dir: np.ndarray
    orbit: Orbit
    occluder_width_m: float
    vehicles: tuple[PlacedVehicle, ...] = ()


@dataclass(frozen=True)
class PlacedVehicle:
    """A non-target vehicle of the world.

    Attributes:
        name: "car", a confuser's template name ("ifv", "truck6x6"), the name given with a
            ``clutter_meshes`` entry of ``build_world``, or "clutter-<i>" for the i-th one without.
        position_m: (3,) its mesh origin in the world frame (built-in vehicles: on the ground under
            their centre), metres.
        yaw_rad: heading of its x axis from the world x axis, radians.
        radius_m: horizontal bounding radius about its origin, metres.

    """

    name: str
    position_m: tuple[float, float, float]
    yaw_rad: float
    radius_m: float


# terrain ------------------------------------------------------------------------------------------


def terrain_height(
    x: np.ndarray, y: np.ndarray, waves: np.ndarray, center: np.ndarray
) -> np.ndarray:
    """Gentle terrain height, metres: sum of plane waves, flattened to 0 around the target.

    Args:
        x, y: world coordinates, metres (any matching shapes).
        waves: (K, 4) amplitude m, wavelength m, direction rad, phase rad.
        center: (2,) target position; the terrain is flat (z = 0) within ~15 m of it.

    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    h = np.zeros(np.broadcast(x, y).shape)
    for amp, lam, ang, ph in waves:
        h += amp * np.sin(2 * np.pi * (x * np.cos(ang) + y * np.sin(ang)) / lam + ph)
    r = np.hypot(x - center[0], y - center[1])
    t = np.clip((r - 15.0) / 35.0, 0.0, 1.0)
    return h * t * t * (3 - 2 * t)


def _terrain_mesh(waves: np.ndarray, center: np.ndarray) -> Mesh:
    n = int(round(2 * _TERRAIN_HALF_M / _TERRAIN_STEP_M)) + 1
    g = np.linspace(-_TERRAIN_HALF_M, _TERRAIN_HALF_M, n)
    X, Y = np.meshgrid(g, g, indexing="xy")
    Z = terrain_height(X, Y, waves, center)
    v = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    i = np.arange(n - 1)
    I, J = np.meshgrid(i, i, indexing="xy")
    a = (J * n + I).ravel()
    b, c, d = a + 1, a + n + 1, a + n
    t = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    inner = Mesh(v, t, np.full(len(t), M.GROUND))
    # flat outer ground up to the horizon, a ring of four trapezoids around the detailed square
    H, h = _HORIZON_HALF_M, _TERRAIN_HALF_M
    z0 = -0.3
    ov = np.array(
        [
            [-H, -H, z0],
            [H, -H, z0],
            [H, H, z0],
            [-H, H, z0],
            [-h, -h, z0],
            [h, -h, z0],
            [h, h, z0],
            [-h, h, z0],
        ]
    )
    ot = np.array(
        [[0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    )
    outer = Mesh(ov, ot, np.full(len(ot), M.GRASS))
    return merge([inner, outer])


# objects ------------------------------------------------------------------------------------------


def building(
    footprint: tuple[float, float],
    height_m: float,
    rng: np.random.Generator,
    wall_material: int = M.FACADE,
) -> Mesh:
    """A building centred at the origin (1 m of basement below z = 0), with roof details."""
    lx, ly = footprint
    parts = [
        box((lx, ly, height_m + 1.0), (0, 0, 0.5 * (height_m - 1.0)), wall_material, bottom=False)
    ]
    if height_m < 11.0 and rng.random() < 0.5:
        ridge = min(lx, ly) * rng.uniform(0.25, 0.4)
        roof = gable_roof(lx + 0.6, ly + 0.6, ridge, (0, 0, height_m), M.ROOF_TILE)
        if ly > lx:  # ridge along the long side
            roof = gable_roof(ly + 0.6, lx + 0.6, ridge, (0, 0, height_m), M.ROOF_TILE).transformed(
                pose(rot_z(np.pi / 2))
            )
        parts.append(roof)
        parts.append(
            box((0.6, 0.6, ridge + 1.2), (0.25 * lx, 0.1 * ly, height_m + 0.5 * ridge), M.BRICK)
        )
        return merge(parts)
    parts.append(box((lx - 0.4, ly - 0.4, 0.05), (0, 0, height_m + 0.02), M.ROOF))
    # parapet
    pw, ph = 0.25, rng.uniform(0.5, 1.1)
    for sx, sy, cx, cy in (
        (lx, pw, 0, 0.5 * (ly - pw)),
        (lx, pw, 0, -0.5 * (ly - pw)),
        (pw, ly, 0.5 * (lx - pw), 0),
        (pw, ly, -0.5 * (lx - pw), 0),
    ):
        parts.append(box((sx, sy, ph), (cx, cy, height_m + 0.5 * ph), M.CONCRETE, bottom=False))
    # roof details: stair housing, air-conditioning units, water tank
    if min(lx, ly) > 8.0:
        sx, sy = rng.uniform(3, 5), rng.uniform(3, 4.5)
        cx, cy = rng.uniform(-0.25, 0.25) * lx, rng.uniform(-0.25, 0.25) * ly
        parts.append(box((sx, sy, 2.8), (cx, cy, height_m + 1.4), M.CONCRETE, bottom=False))
    for _ in range(rng.integers(2, 7)):
        sx, sy, sz = rng.uniform(0.8, 2.2), rng.uniform(0.8, 1.6), rng.uniform(0.6, 1.4)
        cx = rng.uniform(-0.5, 0.5) * (lx - sx - 1.0)
        cy = rng.uniform(-0.5, 0.5) * (ly - sy - 1.0)
        parts.append(box((sx, sy, sz), (cx, cy, height_m + 0.5 * sz), M.METAL, bottom=False))
    if rng.random() < 0.4:
        r = rng.uniform(0.8, 1.4)
        cx, cy = rng.uniform(-0.3, 0.3) * lx, rng.uniform(-0.3, 0.3) * ly
        parts.append(cylinder(r, 2.0, 14, M.METAL, center=(cx, cy, height_m + 2.2)))
        for dx, dy in ((-0.6, -0.6), (0.6, -0.6), (0.6, 0.6), (-0.6, 0.6)):
            parts.append(
                box((0.12, 0.12, 1.2), (cx + dx * r, cy + dy * r, height_m + 0.6), M.METAL)
            )
    return merge(parts)


def tree(rng: np.random.Generator, height_m: float) -> Mesh:
    """A tree on the ground at the origin: trunk, a few branches, and a sparse crown of leaf clumps.

    The crown is made of many small separate clumps with gaps between them, so rays (LIDAR) partly
    penetrate it and the ground shows through from above.
    """
    crown_r = height_m * rng.uniform(0.22, 0.32)
    crown_z = height_m - crown_r * rng.uniform(0.9, 1.1)
    trunk_r = 0.06 + 0.02 * height_m
    parts = [
        cylinder(
            trunk_r,
            crown_z + 1.0,
            8,
            M.BARK,
            center=(0, 0, 0.5 * (crown_z - 1.0)),
            radius_end=0.7 * trunk_r,
        )
    ]
    for _ in range(4):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(0.4, 1.0)
        length = crown_r * rng.uniform(0.6, 0.9)
        d = np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
        c = np.array([0, 0, crown_z - 0.3 * crown_r]) + 0.5 * length * d
        b = cylinder(0.5 * trunk_r, length, 6, M.BARK)
        R = _rot_from_z(d)
        parts.append(b.transformed(pose(R, c)))
    n_clumps = int(60 + 36.0 * crown_r**2)
    u = rng.normal(size=(n_clumps, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    rad = crown_r * rng.random(n_clumps) ** 0.4
    centers = u * rad[:, None] * np.array([1.0, 1.0, 0.8]) + np.array([0, 0, crown_z])
    sizes = rng.uniform(0.15, 0.35, n_clumps) * (0.8 + 0.07 * crown_r)
    scale = sizes[:, None] * np.column_stack(
        [np.ones(n_clumps), rng.uniform(0.6, 1.0, n_clumps), rng.uniform(0.4, 0.8, n_clumps)]
    )
    R = _random_rotations(rng, n_clumps)
    # leaf clumps are small tetrahedra: 4 triangles each, sharp-edged like leaf clusters from afar
    tet_v = np.array(
        [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]]
    ) / np.sqrt(3)
    tet_t = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    v = np.einsum("nij,kj->nki", R * scale[:, None, :], tet_v) + centers[:, None, :]
    t = tet_t[None] + 4 * np.arange(n_clumps)[:, None, None]
    parts.append(Mesh(v.reshape(-1, 3), t.reshape(-1, 3), np.full(4 * n_clumps, M.FOLIAGE)))
    return merge(parts)


def _rot_from_z(d: np.ndarray) -> np.ndarray:
    z = d / np.linalg.norm(d)
    x = np.cross([0.0, 1.0, 0.0], z) if abs(z[1]) < 0.9 else np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3, 3) uniformly random rotations (from unit quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=1),
        ],
        axis=1,
    )


# layout -------------------------------------------------------------------------------------------


@dataclass
class _Item:
    mesh: Mesh  # in world frame
    x: float
    y: float
    radius: float  # horizontal bounding radius, metres
    height: float  # top above its ground, metres
    kind: str
    z: float = 0.0  # its origin's height, metres
    yaw: float = 0.0  # heading, radians
    name: str = ""  # vehicles: the name PlacedVehicle reports


@dataclass(frozen=True)
class _Spot:
    """Where an object goes: position and heading, and the disc and height it takes up (metres)."""

    x: float
    y: float
    yaw: float
    radius: float
    height: float


@dataclass(frozen=True)
class _CityPlan:
    """What the seed fixes before anything is placed: street grid, target place, terrain, sun."""

    grid_ang: float  # heading of the street grid's u axis, radians
    to_world: np.ndarray  # (2, 2) grid (u, v) -> world (x, y)
    spacing: np.ndarray  # (2,) distance between parallel streets along u and v, metres
    widths: np.ndarray  # (2,) carriageway widths, metres
    offset: np.ndarray  # (2,) position of the street grid along u and v, metres
    on_street: bool  # the target drives along a street (else it stands on an open square)
    target_xy: np.ndarray  # (2,) target position, world frame, metres
    heading: float  # target heading, radians
    waves: np.ndarray  # (6, 4) terrain plane waves (see terrain_height)
    sun_dir: np.ndarray  # (3,) unit vector from the ground towards the sun

    def ground(self, x: float, y: float) -> float:
        """Terrain height at (x, y), metres."""
        return terrain_height(x, y, self.waves, self.target_xy)

    def street_dist(self, x: float, y: float) -> tuple[float, float]:
        """Signed distances to the nearest carriageway edge along u and v (negative: on it)."""
        uv = self.to_world.T @ np.array([x - 0.0, y - 0.0])
        offset, spacing = self.offset, self.spacing
        du = np.abs((uv[0] - offset[0] + 0.5 * spacing[0]) % spacing[0] - 0.5 * spacing[0])
        dv = np.abs((uv[1] - offset[1] + 0.5 * spacing[1]) % spacing[1] - 0.5 * spacing[1])
        return du - 0.5 * self.widths[0], dv - 0.5 * self.widths[1]


class _Keepout:
    """Rules that decide whether an object may stand somewhere in this run's world."""

    def __init__(self, target_xy: np.ndarray, orbit: Orbit, aim_z: float) -> None:
        self.t = target_xy
        c = orbit.center[:2]
        self.c = c
        self.radius = orbit.radius_m
        self.cam_h = orbit.height_m + aim_z  # camera height above the target's ground
        self.tan_el = orbit.height_m / orbit.radius_m

    def flyable(self, x: float, y: float, r: float, h: float) -> bool:
        """False when the UAV would fly into the object."""
        d = np.hypot(x - self.c[0], y - self.c[1])
        near_path = abs(d - self.radius) < r + _UAV_CLEARANCE_M
        return not (near_path and h > self.cam_h - _UAV_CLEARANCE_M)

    def cannot_hide(self, x: float, y: float, r: float, h: float) -> bool:
        """False when the object could hide the whole target from some orbit position."""
        near = max(np.hypot(x - self.t[0], y - self.t[1]) - r, 0.0)
        if near > self.radius:
            return True
        return h <= _TARGET_TOP_M + near * self.tan_el


class _Layout:
    """The objects placed so far, and the rules for placing more."""

    def __init__(self, plan: _CityPlan, keep: _Keepout) -> None:
        self.plan = plan
        self.keep = keep
        self.items: list[_Item] = []
        self._occupied = np.zeros((0, 3))  # occupied discs (x, y, radius)

    def free(self, x: float, y: float, r: float) -> bool:
        """Whether a disc of radius r at (x, y) keeps clear of the target and of every object."""
        t = self.plan.target_xy
        if np.hypot(x - t[0], y - t[1]) < r + 5.0:
            return False
        d = np.hypot(self._occupied[:, 0] - x, self._occupied[:, 1] - y)
        return bool(np.all(d > r + self._occupied[:, 2] + 0.5))

    def add(
        self, mesh_local: Mesh, spot: _Spot, kind: str, sink: float = 0.0, name: str = ""
    ) -> None:
        """Stand a mesh (its own frame) on the terrain at spot, sunk by sink metres."""
        x, y = spot.x, spot.y
        z = float(self.plan.ground(x, y)) - sink
        mesh = place(mesh_local, x, y, z, spot.yaw)
        self.items.append(_Item(mesh, x, y, spot.radius, spot.height, kind, z, spot.yaw, name))
        self._occupied = np.vstack([self._occupied, [[x, y, spot.radius]]])


@dataclass(frozen=True)
class _PlacedTarget:
    local: Mesh  # in its own frame
    world: Mesh  # in the world frame
    T_world_target: np.ndarray  # (4, 4)


def build_world(
    sc: Scenario,
    seed: int,
    *,
    target_mesh: Mesh | None = None,
    target_name: str | None = None,
    clutter_meshes: Sequence[Mesh | tuple[str, Mesh]] = (),
    config: SimConfig | None = None,
) -> World:
    """Build the world of one scenario run.

    Args:
        sc: scenario run (range, obliquity, frames; the absent ratio drives the occluder).
        seed: world seed; the same seed gives the same world.
        target_mesh: the target (vehicle frame: origin on the ground, x forward, z up), replacing
            the vehicle `target_name` names.
        target_name: name reported in the truth; without target_mesh, the vehicle of
            `atr.sim.vehicles.VEHICLES` to use as the target (default "t72"; "target" for a
            target_mesh without a name). The world's own IFV or 6x6 truck is left out when it is
            the target.
        clutter_meshes: extra confuser vehicles placed on open ground near the target, each a Mesh
            (reported as "clutter-<i>") or a (name, Mesh) pair.
        config: simulator settings.

    Returns:
        The world, including the run's orbit.

    Raises:
        InputError: an empty target mesh, or a target name no vehicle has (without target_mesh).

    """
    cfg = config or SimConfig()
    rng = np.random.default_rng([seed, 0x5EED])
    name, tmesh = _target(target_mesh, target_name)
    plan = _city_plan(rng, cfg)
    txy = plan.target_xy
    # a mesh whose origin is not on its lowest point (common in CAD files) still stands on the ground
    base_z = -float(tmesh.bounds()[0][2])
    T_world_target = pose(rot_z(plan.heading), (txy[0], txy[1], base_z))
    target = _PlacedTarget(tmesh, tmesh.transformed(T_world_target), T_world_target)
    # the run's orbit (seed, scenario, run)
    orbit_rng = np.random.default_rng([seed, sc.scenario, sc.run, 0x0B17])
    orbit = make_orbit(sc, np.array([txy[0], txy[1], 0.0]), orbit_rng, cfg)
    ground_rects = _ground_rects(plan, rng)
    layout = _Layout(plan, _Keepout(txy, orbit, 1.1))
    _add_buildings(layout, rng)
    _add_trees(layout, rng)
    _add_walls(layout, rng)
    _add_parked_cars(layout, rng)
    _add_confusers(layout, rng, sc.range_m, _confusers(rng, name, clutter_meshes))
    terrain = _terrain_mesh(plan.waves, txy)
    items = layout.items
    occluder_width, occ = 0.0, None
    if sc.absent_scenes > 0:
        scene = merge([terrain] + [it.mesh for it in items])
        occ, occluder_width, inside = _tuned_occluder(sc, cfg, orbit, target, scene, rng)
        # nothing may stand inside the occluder building
        items = [it for it in items if not inside(it.x, it.y, it.radius)]
    static_parts = [terrain] + [it.mesh for it in items] + ([occ] if occ is not None else [])
    return World(
        seed=seed,
        static=merge(static_parts),
        target=target.world,
        target_name=name,
        T_world_target=T_world_target,
        target_local=tmesh,
        ground_rects=ground_rects,
        sun_dir=plan.sun_dir,
        orbit=orbit,
        occluder_width_m=occluder_width,
        vehicles=tuple(
            PlacedVehicle(it.name, (it.x, it.y, it.z), float(it.yaw), it.radius)
            for it in items
            if it.name
        ),
    )


def _target(target_mesh: Mesh | None, target_name: str | None) -> tuple[str, Mesh]:
    """The target's name and mesh (vehicle frame)."""
    if target_mesh is None:
        name = target_name or "t72"
        return name, vehicle(name)
    if target_mesh.n_triangles == 0:
        raise InputError("target mesh has no triangles")
    return target_name or "target", target_mesh


def _city_plan(rng: np.random.Generator, cfg: SimConfig) -> _CityPlan:
    """The street grid, the target's place and heading, the terrain and the sun (seed only)."""
    grid_ang = rng.uniform(0, np.pi / 2)
    spacing = rng.uniform(*_STREET_SPACING_M, 2)
    widths = rng.uniform(*_STREET_WIDTH_M, 2)
    offset = rng.uniform(0, 1, 2) * spacing
    cg, sg = np.cos(grid_ang), np.sin(grid_ang)
    to_world = np.array([[cg, -sg], [sg, cg]])
    on_street = rng.random() < 0.5
    t_uv = rng.uniform(-25, 25, 2)
    if on_street:  # snap the target onto a street along u, driving along it
        k = np.round((t_uv[1] - offset[1]) / spacing[1])
        t_uv[1] = offset[1] + k * spacing[1] + rng.uniform(-0.15, 0.15) * widths[1]
        heading = grid_ang + (0.0 if rng.random() < 0.5 else np.pi) + rng.normal(0, 0.1)
    else:
        heading = rng.uniform(0, 2 * np.pi)
    waves = np.column_stack(
        [
            rng.uniform(0.15, 0.5, 6),
            rng.uniform(40, 220, 6),
            rng.uniform(0, np.pi, 6),
            rng.uniform(0, 2 * np.pi, 6),
        ]
    )
    sun_el = np.deg2rad(rng.uniform(*cfg.sun_elevation_deg))
    sun_az = rng.uniform(0, 2 * np.pi)
    sun_dir = np.array(
        [np.cos(sun_el) * np.cos(sun_az), np.cos(sun_el) * np.sin(sun_az), np.sin(sun_el)]
    )
    return _CityPlan(
        grid_ang,
        to_world,
        spacing,
        widths,
        offset,
        on_street,
        to_world @ t_uv,
        heading,
        waves,
        sun_dir,
    )


def _ground_rects(plan: _CityPlan, rng: np.random.Generator) -> np.ndarray:
    """The ground map: streets with sidewalks, and a square around a target that is off the street."""
    rects = []
    n_lines = int(_TERRAIN_HALF_M * 2 / plan.spacing.min()) + 2
    for axis in (0, 1):
        for k in range(-n_lines, n_lines + 1):
            c = plan.offset[axis] + k * plan.spacing[axis]
            if abs(c) > _TERRAIN_HALF_M + plan.spacing[axis]:
                continue
            x, y = plan.to_world @ (np.array([0.0, c]) if axis == 0 else np.array([c, 0.0]))
            ang = plan.grid_ang if axis == 0 else plan.grid_ang + np.pi / 2
            half_w = 0.5 * plan.widths[1 - axis]
            cos_sin = [np.cos(ang), np.sin(ang)]
            half_l = _TERRAIN_HALF_M * 1.5
            rects.append([x, y, half_l, half_w + _SIDEWALK_M, *cos_sin, M.CONCRETE, 0])
            rects.append([x, y, half_l, half_w, *cos_sin, M.ASPHALT, 1])
    if not plan.on_street:
        tx, ty = plan.target_xy
        half_u = rng.uniform(10, 16)
        half_v = half_u * rng.uniform(0.7, 1.0)
        cos_sin = [np.cos(plan.heading), np.sin(plan.heading)]
        material = M.CONCRETE if rng.random() < 0.5 else M.DIRT
        rects.append([tx, ty, half_u, half_v, *cos_sin, material, 0])
    return np.array(rects, dtype=np.float64)


def _add_buildings(layout: _Layout, rng: np.random.Generator) -> None:
    """Buildings on one to nine lots of every block between the streets (15 % are parks)."""
    offset, spacing, widths = layout.plan.offset, layout.plan.spacing, layout.plan.widths
    n_blocks = [int(_CITY_HALF_M / s) + 2 for s in spacing]
    for bu in range(-n_blocks[0], n_blocks[0] + 1):
        for bv in range(-n_blocks[1], n_blocks[1] + 1):
            u0 = offset[0] + bu * spacing[0] + 0.5 * widths[0] + _SIDEWALK_M + 1.0
            u1 = offset[0] + (bu + 1) * spacing[0] - 0.5 * widths[0] - _SIDEWALK_M - 1.0
            v0 = offset[1] + bv * spacing[1] + 0.5 * widths[1] + _SIDEWALK_M + 1.0
            v1 = offset[1] + (bv + 1) * spacing[1] - 0.5 * widths[1] - _SIDEWALK_M - 1.0
            if rng.random() < 0.15:  # a park block: only trees
                continue
            nu, nv = int(rng.integers(1, 4)), int(rng.integers(1, 4))
            for iu in range(nu):
                for iv in range(nv):
                    lot_u = (u0 + (u1 - u0) * iu / nu, u0 + (u1 - u0) * (iu + 1) / nu)
                    lot_v = (v0 + (v1 - v0) * iv / nv, v0 + (v1 - v0) * (iv + 1) / nv)
                    _add_building_on_lot(layout, rng, lot_u, lot_v)


def _add_building_on_lot(
    layout: _Layout,
    rng: np.random.Generator,
    lot_u: tuple[float, float],
    lot_v: tuple[float, float],
) -> None:
    (lu0, lu1), (lv0, lv1) = lot_u, lot_v
    fu = (lu1 - lu0) * rng.uniform(0.6, 0.92)
    fv = (lv1 - lv0) * rng.uniform(0.6, 0.92)
    cu = lu0 + 0.5 * (lu1 - lu0) + rng.uniform(-0.5, 0.5) * (lu1 - lu0 - fu)
    cv = lv0 + 0.5 * (lv1 - lv0) + rng.uniform(-0.5, 0.5) * (lv1 - lv0 - fv)
    x, y = layout.plan.to_world @ np.array([cu, cv])
    if max(abs(x), abs(y)) > _CITY_HALF_M:
        return
    heights = [rng.uniform(5, 10), rng.uniform(10, 22), rng.uniform(18, 32)]
    h = float(rng.choice(heights, p=[0.4, 0.45, 0.15]))
    wall = M.BRICK if rng.random() < 0.3 else M.FACADE
    mesh = building((fu, fv), h, rng, wall)
    r = 0.5 * np.hypot(fu, fv)
    keep = layout.keep
    allowed = keep.flyable(x, y, r, h + 3.0) and keep.cannot_hide(x, y, r, h + 3.0)
    if allowed and layout.free(x, y, r):
        layout.add(mesh, _Spot(x, y, layout.plan.grid_ang, r, h), "building", sink=0.0)


def _add_trees(layout: _Layout, rng: np.random.Generator) -> None:
    """Up to 320 trees along the sidewalks and in open places, denser near the target."""
    plan = layout.plan
    tx, ty = plan.target_xy
    n_trees = 0
    attempts = 0
    while n_trees < 320 and attempts < 5000:
        attempts += 1
        x, y = rng.uniform(-_CITY_HALF_M, _CITY_HALF_M, 2)
        du, dv = plan.street_dist(x, y)
        along = (0 < du < _SIDEWALK_M + 2.0) or (0 < dv < _SIDEWALK_M + 2.0)
        if du < 0 or dv < 0:
            continue  # on the carriageway
        near = np.hypot(x - tx, y - ty) < 150.0
        if not along and rng.random() < (0.3 if near else 0.7):
            continue
        h = rng.uniform(5.0, 13.0)
        r = 0.3 * h
        if np.hypot(x - tx, y - ty) < _CLEAR_AROUND_TARGET_M + r:
            continue
        if layout.keep.flyable(x, y, r, h) and layout.free(x, y, r * 0.6):
            layout.add(tree(rng, h), _Spot(x, y, 0.0, r * 0.6, h), "tree", sink=0.3)
            n_trees += 1


def _add_walls(layout: _Layout, rng: np.random.Generator) -> None:
    """Low brick and concrete walls off the streets."""
    plan = layout.plan
    for _ in range(40):
        x, y = rng.uniform(-_CITY_HALF_M * 0.6, _CITY_HALF_M * 0.6, 2)
        du, dv = plan.street_dist(x, y)
        if min(du, dv) < _SIDEWALK_M:
            continue
        length, h = rng.uniform(6, 20), rng.uniform(1.2, 2.2)
        yaw = plan.grid_ang + (0 if rng.random() < 0.5 else np.pi / 2)
        mat = M.BRICK if rng.random() < 0.5 else M.CONCRETE
        wall = box((length, 0.3, h + 0.5), (0, 0, 0.5 * h - 0.25), mat, bottom=False)
        if layout.keep.flyable(x, y, 0.5 * length, h) and layout.free(x, y, 0.5 * length):
            layout.add(wall, _Spot(x, y, yaw, 0.5 * length, h), "wall")


def _add_parked_cars(layout: _Layout, rng: np.random.Generator) -> None:
    """Cars parked along the kerbs, in five paints."""
    plan = layout.plan
    for _ in range(400):
        x, y = rng.uniform(-_CITY_HALF_M, _CITY_HALF_M, 2)
        du, dv = plan.street_dist(x, y)
        if -1.6 < dv < -0.8:
            yaw = plan.grid_ang + (0 if rng.random() < 0.5 else np.pi)
        elif -1.6 < du < -0.8:
            yaw = plan.grid_ang + np.pi / 2 + (0 if rng.random() < 0.5 else np.pi)
        else:
            continue
        if layout.free(x, y, 2.3) and layout.keep.flyable(x, y, 2.3, 1.5):
            paint = M.CAR_PAINTS[int(rng.integers(len(M.CAR_PAINTS)))]
            layout.add(car(paint), _Spot(x, y, yaw, 2.3, 1.5), "car", name="car")


def _military_paint(rng: np.random.Generator) -> int:
    return M.OLIVE if rng.random() < 0.7 else M.SAND


def _confusers(
    rng: np.random.Generator, target_name: str, clutter: Sequence[Mesh | tuple[str, Mesh]]
) -> list[tuple[str, Mesh]]:
    """The world's IFV and 6x6 truck (either left out when it is the target), then the clutter."""
    own = [("ifv", ifv(_military_paint(rng))), ("truck6x6", truck_6x6(_military_paint(rng)))]
    named = [c if isinstance(c, tuple) else (f"clutter-{i}", c) for i, c in enumerate(clutter)]
    return [(n, m) for n, m in own if n != target_name] + named


def _add_confusers(
    layout: _Layout, rng: np.random.Generator, range_m: float, confusers: list[tuple[str, Mesh]]
) -> None:
    """Each confuser on open ground 14 m or more from the target, within half the range."""
    for confuser_name, mesh in confusers:
        lo, hi = mesh.bounds()
        r = float(np.hypot(*np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))))
        for _ in range(200):
            d = rng.uniform(14.0, max(20.0, 0.5 * range_m))
            a = rng.uniform(0, 2 * np.pi)
            x, y = layout.plan.target_xy + d * np.array([np.cos(a), np.sin(a)])
            if layout.free(x, y, r) and layout.keep.flyable(x, y, r, float(hi[2])):
                spot = _Spot(x, y, rng.uniform(0, 2 * np.pi), r, float(hi[2] - lo[2]))
                layout.add(mesh, spot, "confuser", sink=float(lo[2]), name=confuser_name)
                break


def frame_times_s(sc: Scenario, cfg: SimConfig) -> np.ndarray:
    """Times of the run's frames since the start of the run, seconds."""
    return np.arange(sc.n_frames) * cfg.frame_interval_s(sc.range_m)


# the occluder -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Occluder:
    """The tall building beside the target: an upright box (metres, radians)."""

    center_xy: np.ndarray  # (2,) footprint centre, world frame
    yaw: float  # heading of its depth axis, pointing away from the target
    depth: float  # along yaw
    height: float
    width: float = 0.0  # across yaw: what the tuning sets

    def inside(self, x: float, y: float, r: float) -> bool:
        """Whether a disc of radius r at (x, y) overlaps the footprint."""
        u = np.array([np.cos(self.yaw), np.sin(self.yaw)])
        du = (x - self.center_xy[0]) * u[0] + (y - self.center_xy[1]) * u[1]
        dv = -(x - self.center_xy[0]) * u[1] + (y - self.center_xy[1]) * u[0]
        return abs(du) < 0.5 * self.depth + r and abs(dv) < 0.5 * self.width + r


def _tuned_occluder(
    sc: Scenario,
    cfg: SimConfig,
    orbit: Orbit,
    target: _PlacedTarget,
    static: Mesh,
    rng: np.random.Generator,
) -> tuple[Mesh | None, float, Callable[[float, float, float], bool]]:
    """A tall building beside the target, widened until the run's share of scenes without a visible
    target reaches the scenario's absent ratio (bisection on the width; ray-box tests, no
    re-meshing).

    Returns:
        the building (None when clutter alone already hides the target often enough), its width in
        metres, and a test inside(x, y, r) telling whether a disc overlaps its footprint.

    """
    # late import: visibility needs a built scene
    from atr.sim.visibility import target_visibility_rays

    times = frame_times_s(sc, cfg)
    cams = np.array([(orbit.T_world_imu(t) @ cfg.T_imu_cam_matrix)[:3, 3] for t in times])
    pts, seen, self_vis = target_visibility_rays(
        static, target.world, target.local, target.T_world_target, cams, cfg
    )
    box_ = _occluder_box(rng, target.T_world_target[:2, 3], orbit)
    hidden_share = _hidden_share(cams, pts, seen, self_vis, box_, cfg.present_min_visible_fraction)
    # the run's share of Table II's scenes without target (half a scene below: integer counts)
    wanted = (sc.absent_scenes - 0.5) / sc.n_scenes
    if hidden_share(0.0) >= wanted:
        return None, 0.0, lambda x, y, r: False
    box_ = replace(box_, width=_bisect_width(hidden_share, wanted))
    rng_b = np.random.default_rng(int(rng.integers(1 << 31)))
    occ = building((box_.depth, box_.width), box_.height, rng_b, M.FACADE)
    occ = place(occ, box_.center_xy[0], box_.center_xy[1], 0.0, box_.yaw)
    return occ, float(box_.width), box_.inside


def _occluder_box(rng: np.random.Generator, target_xy: np.ndarray, orbit: Orbit) -> _Occluder:
    """Where the occluder stands (11-14 m from the target), how deep and how tall (width still 0)."""
    az = rng.uniform(0, 2 * np.pi)
    dist = rng.uniform(11.0, 14.0)
    depth = rng.uniform(8.0, 12.0)
    u = np.array([np.cos(az), np.sin(az)])
    center_xy = target_xy + (dist + 0.5 * depth) * u
    height = min(45.0, _TARGET_TOP_M + (dist + depth) * orbit.height_m / orbit.radius_m + 6.0)
    return _Occluder(center_xy, az, depth, max(height, 12.0))


def _hidden_share(
    cams: np.ndarray,
    pts: np.ndarray,
    seen: np.ndarray,
    self_vis: np.ndarray,
    box_: _Occluder,
    present_min_visible_fraction: float,
) -> Callable[[float], float]:
    """The share of the run's scenes without a visible target, as a function of the occluder width.

    Args:
        cams: (F, 3) camera centres; pts: (S, 3) target samples; seen, self_vis: (F, S) visibility
            in the scene and of the target alone (`target_visibility_rays`).
        box_: the occluder (its width is the function's argument).
        present_min_visible_fraction: a frame has the target at or above this visible fraction.

    """
    n_self = np.maximum(self_vis.sum(axis=1), 1)
    ends = np.broadcast_to(pts, (cams.shape[0],) + pts.shape)

    def hidden_share(width: float) -> float:
        if width <= 0:
            vis = seen
        else:
            vis = seen & ~_rays_hit_box(cams, ends, replace(box_, width=width))
        frac = vis.sum(axis=1) / n_self
        present = frac >= present_min_visible_fraction
        # a scene is the pair (k, k+1): it has the target when both frames do
        scene_present = present[:-1] & present[1:]
        return 1.0 - scene_present.mean()

    return hidden_share


def _bisect_width(hidden_share: Callable[[float], float], wanted: float) -> float:
    """The narrowest width (0-120 m, ten halvings) whose hidden share reaches wanted."""
    lo, hi = 0.0, 120.0
    if hidden_share(hi) < wanted:
        lo = hi
    else:
        for _ in range(10):
            mid = 0.5 * (lo + hi)
            if hidden_share(mid) < wanted:
                lo = mid
            else:
                hi = mid
    return hi if lo < hi else lo


def _rays_hit_box(origins: np.ndarray, ends: np.ndarray, box_: _Occluder) -> np.ndarray:
    """Whether segments origins (F, 3) -> ends (F, S, 3) pass through an upright box (slab test)."""
    c, s = np.cos(box_.yaw), np.sin(box_.yaw)
    R = np.array([[c, s], [-s, c]])  # world -> box frame (rotation by -yaw)
    d = ends - origins[:, None, :]
    o = np.broadcast_to(origins[:, None, :], d.shape)
    oxy = (o[..., :2] - box_.center_xy) @ R.T
    dxy = d[..., :2] @ R.T
    lo_b = np.array([-0.5 * box_.depth, -0.5 * box_.width, -5.0])
    hi_b = np.array([0.5 * box_.depth, 0.5 * box_.width, box_.height])
    O = np.concatenate([oxy, o[..., 2:3] + np.zeros_like(d[..., 2:3])], axis=-1)
    D = np.concatenate([dxy, d[..., 2:3]], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / D
        t0 = (lo_b - O) * inv
        t1 = (hi_b - O) * inv
    tmin = np.nanmax(np.minimum(t0, t1), axis=-1)
    tmax = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (tmax >= np.maximum(tmin, 0.0)) & (tmin <= 1.0)
