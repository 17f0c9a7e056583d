"""Numba kernels: solid procedural textures (albedo per surface point) for the materials table.

Written here because no library in the project evaluates band-limited solid textures per ray hit.
Every pattern is a function of the world position (and, for oriented patterns such as bricks and
windows, of the surface normal's dominant axis), so it is fixed to the world. Octaves whose
wavelength is shorter than ~2 pixel footprints fade to their mean: no aliasing flicker at long
range.
"""

from __future__ import annotations

import numba
import numpy as np

from atr.sim import materials as M

# contrast of the micro detail per material index (0: none); see materials.py for the indices
_ROUGHNESS = np.array(
    [
        0.5,  # ground (resolved per point; this row unused)
        0.55,  # asphalt
        0.35,  # concrete
        0.3,  # brick
        0.25,  # facade
        0.5,  # roof
        0.3,  # roof tile
        0.6,  # grass
        0.6,  # foliage
        0.5,  # bark
        0.25,  # camouflage
        0.3,  # metal
        0.2,  # rubber
        0.05,  # glass
        0.25,  # olive drab
        0.3,  # canvas
        0.06,
        0.06,
        0.06,
        0.06,
        0.06,  # paints
        0.6,  # dirt
        0.25,  # default
        0.25,  # sand paint
    ]
)


@numba.njit(cache=True)
def _hash(ix: int, iy: int, iz: int, seed: int) -> float:
    h = (ix * 374761393 + iy * 668265263 + iz * 1440662683 + seed * 2246822519) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h = ((h ^ (h >> 16)) * 2246822519) & 0xFFFFFFFF
    h = h ^ (h >> 15)
    return h / 4294967296.0


@numba.njit(cache=True)
def _smooth(t: float) -> float:
    return t * t * (3.0 - 2.0 * t)


@numba.njit(cache=True)
def value_noise(x: float, y: float, z: float, seed: int) -> float:
    """Trilinear value noise in [0, 1) with unit lattice spacing."""
    fx, fy, fz = np.floor(x), np.floor(y), np.floor(z)
    ix, iy, iz = int(fx), int(fy), int(fz)
    tx, ty, tz = _smooth(x - fx), _smooth(y - fy), _smooth(z - fz)
    c000 = _hash(ix, iy, iz, seed)
    c100 = _hash(ix + 1, iy, iz, seed)
    c010 = _hash(ix, iy + 1, iz, seed)
    c110 = _hash(ix + 1, iy + 1, iz, seed)
    c001 = _hash(ix, iy, iz + 1, seed)
    c101 = _hash(ix + 1, iy, iz + 1, seed)
    c011 = _hash(ix, iy + 1, iz + 1, seed)
    c111 = _hash(ix + 1, iy + 1, iz + 1, seed)
    a = c000 + tx * (c100 - c000)
    b = c010 + tx * (c110 - c010)
    c = c001 + tx * (c101 - c001)
    d = c011 + tx * (c111 - c011)
    e = a + ty * (b - a)
    f = c + ty * (d - c)
    return e + tz * (f - e)


@numba.njit(cache=True)
def value_noise2(x: float, y: float, seed: int) -> float:
    """Bilinear value noise in [0, 1) with unit lattice spacing."""
    fx, fy = np.floor(x), np.floor(y)
    ix, iy = int(fx), int(fy)
    tx, ty = _smooth(x - fx), _smooth(y - fy)
    c00 = _hash(ix, iy, 0, seed)
    c10 = _hash(ix + 1, iy, 0, seed)
    c01 = _hash(ix, iy + 1, 0, seed)
    c11 = _hash(ix + 1, iy + 1, 0, seed)
    a = c00 + tx * (c10 - c00)
    b = c01 + tx * (c11 - c01)
    return a + ty * (b - a)


@numba.njit(cache=True)
def fbm2(
    u: float,
    v: float,
    wavelength_m: float,
    octaves: int,
    footprint_m: float,
    seed: int,
    gain: float = 0.55,
) -> float:
    """2D fractal value noise in [0, 1], mean 0.5, on surface coordinates; band-limited like fbm."""
    total = 0.0
    norm = 0.0
    amp = 1.0
    lam = wavelength_m
    for k in range(octaves):
        w = (lam / footprint_m - 1.5) / 1.5
        w = min(max(w, 0.0), 1.0)
        if w > 0.0:
            n = value_noise2(u / lam + 17.3 * k, v / lam - 9.1 * k, seed + 101 * k)
        else:
            n = 0.5
        total += amp * (w * n + (1.0 - w) * 0.5)
        norm += amp
        amp *= gain
        lam *= 0.5
    return total / norm


@numba.njit(cache=True)
def fbm(
    x: float, y: float, z: float, wavelength_m: float, octaves: int, footprint_m: float, seed: int
) -> float:
    """Fractal value noise in [0, 1], mean 0.5; octaves finer than ~2 footprints fade out."""
    total = 0.0
    norm = 0.0
    amp = 1.0
    lam = wavelength_m
    for k in range(octaves):
        w = (lam / footprint_m - 1.5) / 1.5
        w = min(max(w, 0.0), 1.0)
        if w > 0.0:
            n = value_noise(
                x / lam + 17.3 * k, y / lam - 9.1 * k, z / lam + 3.7 * k, seed + 101 * k
            )
        else:
            n = 0.5
        total += amp * (w * n + (1.0 - w) * 0.5)
        norm += amp
        amp *= 0.55
        lam *= 0.5
    return total / norm


@numba.njit(cache=True)
def _lines(u: float, period: float, width: float, footprint_m: float) -> float:
    """Coverage (0..1) of lines of given width repeating every period along u, anti-aliased."""
    if footprint_m * 2.0 > period:
        return width / period
    d = abs(u - period * np.floor(u / period + 0.5))
    soft = max(footprint_m, 1e-4)
    c = 0.5 + (0.5 * width - d) / soft
    c = min(max(c, 0.0), 1.0)
    if footprint_m > width:  # thin line seen from afar: keep its mean contribution
        c *= width / footprint_m
    return c


@numba.njit(cache=True)
def _mix(a: float, b: float, t: float) -> float:
    return a + (b - a) * t


@numba.njit(cache=True)
def _ground_class(x: float, y: float, rects: np.ndarray, fp: float, seed: int) -> int:
    cls = -1
    for k in range(rects.shape[0]):
        dx = x - rects[k, 0]
        dy = y - rects[k, 1]
        u = dx * rects[k, 4] + dy * rects[k, 5]
        v = -dx * rects[k, 5] + dy * rects[k, 4]
        if abs(u) <= rects[k, 2] and abs(v) <= rects[k, 3]:
            cls = int(rects[k, 6])
            if rects[k, 7] > 0 and abs(v) < 0.07 and (u / 6.0 - np.floor(u / 6.0)) < 0.5:
                cls = M.PAINT_WHITE  # dashed centre line
    if cls < 0:  # open ground: grass with patches of bare dirt
        cls = M.DIRT if fbm2(x, y, 25.0, 3, fp, seed + 7) > 0.64 else M.GRASS
    return cls


@numba.njit(cache=True)
def _albedo_one(
    mat: int,
    x: float,
    y: float,
    z: float,
    nx: float,
    ny: float,
    nz: float,
    fp: float,
    rects: np.ndarray,
    seed: int,
) -> tuple[float, float, float]:
    s = seed * 7919 + mat * 131
    if mat == M.GROUND:
        mat = _ground_class(x, y, rects, fp, seed)
        s = seed * 7919 + mat * 131
    # planar coordinates: u horizontal along the surface, v vertical (walls) or the other horizontal
    # axis
    if abs(nz) > 0.7:
        u, v = x, y
    elif abs(nx) > abs(ny):
        u, v = y, z
    else:
        u, v = x, z
    r = g = b = 0.2
    if mat == M.GRASS:
        patch = fbm2(u, v, 7.0, 3, fp, s)
        fine = fbm2(u, v, 0.5, 6, fp, s + 1, 0.8)
        blade = fbm2(u, v, 0.06, 2, fp, s + 2, 0.9)
        k = (0.35 + 1.3 * fine) * (0.7 + 0.6 * patch) * (0.6 + 0.8 * blade)
        dry = min(max((patch - 0.55) * 4.0, 0.0), 1.0)
        r = _mix(0.075, 0.19, dry) * k
        g = _mix(0.15, 0.17, dry) * k
        b = _mix(0.04, 0.07, dry) * k
    elif mat == M.ASPHALT:
        fine = fbm2(u, v, 0.25, 5, fp, s, 0.8)
        patch = fbm2(u, v, 6.0, 3, fp, s + 1)
        k = (0.4 + 1.2 * fine) * (0.7 + 0.6 * patch)
        r = g = 0.075 * k
        b = 0.08 * k
    elif mat == M.CONCRETE:
        fine = fbm2(u, v, 0.4, 6, fp, s, 0.75)
        stain = fbm2(u, v, 4.0, 3, fp, s + 1)
        joint = max(_lines(u, 3.0, 0.025, fp), _lines(v, 3.0, 0.025, fp))
        k = (0.55 + 0.9 * fine) * (0.7 + 0.6 * stain) * (1.0 - 0.6 * joint)
        r, g, b = 0.33 * k, 0.32 * k, 0.30 * k
    elif mat == M.BRICK:
        row = np.floor(v / 0.075)
        shift = 0.125 * (row - 2.0 * np.floor(row / 2.0))
        col = np.floor((u + shift) / 0.25)
        tone = 0.75 + 0.5 * _hash(int(col), int(row), 7, s)
        mortar = max(_lines(v, 0.075, 0.012, fp), _lines(u + shift, 0.25, 0.012, fp))
        if fp * 2.0 > 0.075:
            tone = 1.0
        grime = 0.8 + 0.4 * fbm2(u, v, 2.0, 4, fp, s + 3)
        r = _mix(0.26 * tone, 0.34, mortar) * grime
        g = _mix(0.085 * tone, 0.32, mortar) * grime
        b = _mix(0.05 * tone, 0.29, mortar) * grime
    elif mat == M.FACADE:
        tint = value_noise(x / 60.0, y / 60.0, 0.0, s + 5)
        r = _mix(0.42, 0.55, tint)
        g = _mix(0.40, 0.47, tint)
        b = _mix(0.36, 0.36, tint)
        grime = (0.65 + 0.7 * fbm2(u, v, 3.0, 7, fp, s, 0.7)) * (
            0.8 + 0.4 * fbm2(u, v, 0.3, 3, fp, s + 4)
        )
        r *= grime
        g *= grime
        b *= grime
        if abs(nz) < 0.7:
            fu = u / 3.2 - np.floor(u / 3.2)
            fv = v / 3.0 - np.floor(v / 3.0)
            if fp * 2.0 < 0.6 and 0.25 < fu < 0.75 and 0.28 < fv < 0.78:
                frame = (fu < 0.28) or (fu > 0.72) or (fv < 0.32) or (fv > 0.74)
                if frame:
                    r, g, b = 0.5, 0.5, 0.48
                else:
                    refl = fbm2(u, v, 1.0, 3, fp, s + 9)
                    lit = _hash(int(np.floor(u / 3.2)), int(np.floor(v / 3.0)), 3, s)
                    r = 0.03 + 0.06 * refl + 0.05 * lit
                    g = 0.04 + 0.07 * refl + 0.05 * lit
                    b = 0.05 + 0.09 * refl + 0.04 * lit
            elif fp * 2.0 >= 0.6:
                r *= 0.62
                g *= 0.62
                b *= 0.64
    elif mat == M.ROOF:
        k = (0.45 + 1.1 * fbm2(u, v, 0.5, 6, fp, s, 0.8)) * (
            0.7 + 0.6 * fbm2(u, v, 5.0, 2, fp, s + 1)
        )
        r, g, b = 0.12 * k, 0.115 * k, 0.11 * k
    elif mat == M.ROOF_TILE:
        ridge = _lines(z, 0.22, 0.05, fp)
        k = (0.7 + 0.6 * fbm2(u, v, 1.0, 5, fp, s)) * (1.0 - 0.5 * ridge)
        r, g, b = 0.30 * k, 0.10 * k, 0.05 * k
    elif mat == M.FOLIAGE:
        n1 = fbm2(u, v, 0.3, 5, fp, s, 0.8)
        n2 = fbm2(u, v, 3.0, 2, fp, s + 1)
        k = 0.2 + 1.6 * n1
        r = _mix(0.04, 0.10, n2) * k
        g = _mix(0.11, 0.14, n2) * k
        b = 0.03 * k
    elif mat == M.BARK:
        k = 0.6 + 0.8 * fbm2(u * 4.0, v * 0.5, 0.5, 4, fp, s)
        r, g, b = 0.10 * k, 0.075 * k, 0.055 * k
    elif mat == M.CAMO:
        blob = fbm(x, y, z, 2.2, 3, fp * 0.5, s)  # solid noise: no seams across the curved turret
        grime = 0.6 + 0.8 * fbm2(u, v, 0.3, 5, fp, s + 2, 0.75)
        if blob < 0.42:
            r, g, b = 0.13, 0.085, 0.045
        elif blob > 0.6:
            r, g, b = 0.03, 0.032, 0.025
        else:
            r, g, b = 0.085, 0.10, 0.045
        r *= grime
        g *= grime
        b *= grime
    elif mat == M.METAL:
        k = 0.6 + 0.8 * fbm2(u, v, 0.2, 4, fp, s)
        r, g, b = 0.055 * k, 0.06 * k, 0.055 * k
    elif mat == M.RUBBER:
        k = 0.8 + 0.4 * fbm2(u, v, 0.1, 3, fp, s)
        r = g = b = 0.025 * k
    elif mat == M.GLASS:
        k = 0.6 + 0.8 * fbm2(u, v, 0.8, 3, fp, s)
        r, g, b = 0.03 * k, 0.04 * k, 0.055 * k
    elif mat == M.OLIVE or mat == M.CANVAS or mat == M.SAND or mat == M.DEFAULT:
        if mat == M.OLIVE:
            r, g, b = 0.10, 0.105, 0.05
        elif mat == M.CANVAS:
            r, g, b = 0.17, 0.15, 0.085
        elif mat == M.SAND:
            r, g, b = 0.40, 0.33, 0.21
        else:
            r, g, b = 0.20, 0.20, 0.17
        k = (0.7 + 0.6 * fbm2(u, v, 0.4, 5, fp, s)) * (0.8 + 0.4 * fbm2(u, v, 2.5, 2, fp, s + 1))
        r *= k
        g *= k
        b *= k
    elif M.PAINT_RED <= mat <= M.PAINT_BLACK:
        if mat == M.PAINT_RED:
            r, g, b = 0.45, 0.04, 0.03
        elif mat == M.PAINT_BLUE:
            r, g, b = 0.04, 0.08, 0.30
        elif mat == M.PAINT_WHITE:
            r, g, b = 0.68, 0.68, 0.66
        elif mat == M.PAINT_SILVER:
            r, g, b = 0.42, 0.43, 0.44
        else:
            r, g, b = 0.03, 0.03, 0.035
        k = 0.88 + 0.24 * fbm2(u, v, 0.5, 3, fp, s)
        r *= k
        g *= k
        b *= k
    elif mat == M.DIRT:
        k = (0.4 + 1.2 * fbm2(u, v, 0.4, 6, fp, s, 0.8)) * (
            0.7 + 0.6 * fbm2(u, v, 4.0, 2, fp, s + 1)
        )
        r, g, b = 0.17 * k, 0.12 * k, 0.075 * k
    # micro detail: grain a few centimetres across, strong on rough materials; it fades out with
    # range
    rough = _ROUGHNESS[mat] if mat < _ROUGHNESS.shape[0] else 0.3
    if rough > 0.0:
        d = 2.0 * fbm2(u, v, 0.12, 3, fp, s + 11, 0.9) - 1.0
        k = max(0.15, 1.0 + 2.2 * rough * d)
        r *= k
        g *= k
        b *= k
    return r, g, b


@numba.njit(cache=True, parallel=True)
def albedo(
    mat: np.ndarray,
    pos: np.ndarray,
    nrm: np.ndarray,
    footprint_m: np.ndarray,
    rects: np.ndarray,
    seed: int,
) -> np.ndarray:
    """Linear RGB albedo (N, 3) float32 of N surface points.

    Args:
        mat: (N,) int16 material indices.
        pos: (N, 3) float64 world positions, metres.
        nrm: (N, 3) float64 unit normals.
        footprint_m: (N,) float64 size of one pixel on the surface, metres.
        rects: (K, 7) float64 ground map rectangles (cx, cy, half_u, half_v, cos, sin, material).
        seed: world seed (textures differ between worlds).

    """
    n = mat.shape[0]
    out = np.empty((n, 3), np.float32)
    for i in numba.prange(n):
        r, g, b = _albedo_one(
            int(mat[i]),
            pos[i, 0],
            pos[i, 1],
            pos[i, 2],
            nrm[i, 0],
            nrm[i, 1],
            nrm[i, 2],
            footprint_m[i],
            rects,
            seed,
        )
        out[i, 0] = r
        out[i, 1] = g
        out[i, 2] = b
    return out


@numba.njit(cache=True, parallel=True)
def make_rays(dirs_cam: np.ndarray, R: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """(N, 6) float32 rays (origin, R @ dir) from camera-frame directions (N, 3)."""
    n = dirs_cam.shape[0]
    rays = np.empty((n, 6), np.float32)
    for i in numba.prange(n):
        x, y, z = dirs_cam[i, 0], dirs_cam[i, 1], dirs_cam[i, 2]
        rays[i, 0] = origin[0]
        rays[i, 1] = origin[1]
        rays[i, 2] = origin[2]
        rays[i, 3] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
        rays[i, 4] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
        rays[i, 5] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z
    return rays


@numba.njit(cache=True, parallel=True)
def surface_points(
    rays: np.ndarray,
    t_hit: np.ndarray,
    prim: np.ndarray,
    geom: np.ndarray,
    nrm_in: np.ndarray,
    mat_static: np.ndarray,
    mat_target: np.ndarray,
    target_gid: int,
    focal_px: float,
    grazing_cos_min: float,
    sun: np.ndarray,
    shadow_bias_m: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel: hit position, camera-facing normal, material (-1: sky), footprint, range, cos to
    the sun
    and the shadow ray towards the sun.
    """
    n = rays.shape[0]
    pos = np.empty((n, 3))
    nrm = np.empty((n, 3))
    mat = np.full(n, -1, np.int16)
    fp = np.empty(n)
    dist = np.full(n, np.inf)
    ndl = np.zeros(n)
    sh = np.empty((n, 6), np.float32)
    for i in numba.prange(n):
        t = t_hit[i]
        if not np.isfinite(t):
            continue
        dx, dy, dz = float(rays[i, 3]), float(rays[i, 4]), float(rays[i, 5])
        ln = np.sqrt(dx * dx + dy * dy + dz * dz)
        px = rays[i, 0] + dx * t
        py = rays[i, 1] + dy * t
        pz = rays[i, 2] + dz * t
        nx, ny, nz = float(nrm_in[i, 0]), float(nrm_in[i, 1]), float(nrm_in[i, 2])
        c = (nx * dx + ny * dy + nz * dz) / ln
        if c > 0:
            nx, ny, nz = -nx, -ny, -nz
        else:
            c = -c
        d = t * ln
        pos[i, 0], pos[i, 1], pos[i, 2] = px, py, pz
        nrm[i, 0], nrm[i, 1], nrm[i, 2] = nx, ny, nz
        if geom[i] == target_gid:
            mat[i] = mat_target[min(prim[i], mat_target.shape[0] - 1)]
        else:
            mat[i] = mat_static[min(prim[i], mat_static.shape[0] - 1)]
        # geometric mean of the anisotropic footprint's axes (1 and 1/cos): blurs less than the long
        # axis
        fp[i] = d / focal_px / np.sqrt(max(c, grazing_cos_min))
        dist[i] = d
        ndl[i] = nx * sun[0] + ny * sun[1] + nz * sun[2]
        b = shadow_bias_m + 2e-4 * d
        sh[i, 0] = px + nx * b
        sh[i, 1] = py + ny * b
        sh[i, 2] = pz + nz * b
        sh[i, 3] = sun[0]
        sh[i, 4] = sun[1]
        sh[i, 5] = sun[2]
    return pos, nrm, mat, fp, dist, ndl, sh


@numba.njit(cache=True, parallel=True)
def compose(
    mat: np.ndarray,
    pos: np.ndarray,
    nrm: np.ndarray,
    fp: np.ndarray,
    dist: np.ndarray,
    direct: np.ndarray,
    rays: np.ndarray,
    rects: np.ndarray,
    seed: int,
    sun_rgb: np.ndarray,
    sky_rgb: np.ndarray,
    haze_rgb: np.ndarray,
    zenith_rgb: np.ndarray,
    haze_k: float,
    exposure: float,
) -> np.ndarray:
    """(N, 3) float32 linear RGB after exposure: albedo x (sun + sky), haze; sky where rays miss."""
    n = mat.shape[0]
    out = np.empty((n, 3), np.float32)
    for i in numba.prange(n):
        if mat[i] < 0:
            dx, dy, dz = rays[i, 3], rays[i, 4], rays[i, 5]
            el = dz / np.sqrt(dx * dx + dy * dy + dz * dz)
            w = np.sqrt(min(max(el, 0.0), 1.0))
            for c in range(3):
                out[i, c] = ((1 - w) * haze_rgb[c] + w * zenith_rgb[c]) * 0.75
            continue
        r, g, b = _albedo_one(
            int(mat[i]),
            pos[i, 0],
            pos[i, 1],
            pos[i, 2],
            nrm[i, 0],
            nrm[i, 1],
            nrm[i, 2],
            fp[i],
            rects,
            seed,
        )
        sky = 0.55 + 0.45 * nrm[i, 2]
        f = np.exp(-haze_k * dist[i])
        alb = (r, g, b)
        for c in range(3):
            rad = alb[c] * (direct[i] * sun_rgb[c] + sky * sky_rgb[c])
            out[i, c] = (rad * f + haze_rgb[c] * 0.45 * (1.0 - f)) * exposure
    return out


@numba.njit(cache=True, parallel=True)
def srgb8(lin: np.ndarray) -> np.ndarray:
    """Linear [0, 1] (N, 3) -> sRGB uint8 (N, 3) (IEC 61966-2-1 curve)."""
    n = lin.shape[0]
    out = np.empty((n, 3), np.uint8)
    for i in numba.prange(n):
        for c in range(3):
            x = min(max(lin[i, c], 0.0), 1.0)
            s = 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055
            out[i, c] = np.uint8(s * 255.0 + 0.5)
    return out
