"""Test geometry shared by the descriptor tests (and bench/descriptors.py): a smooth surface with exact normals,
a closed bumpy surface, rigid motions, and the distinctiveness measure."""

import numpy as np


def surface(n=4000, seed=0):
    """A bumpy height field z(x, y) over the unit square with its exact unit normals."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 1, (n, 2))
    x, y = xy[:, 0], xy[:, 1]
    z = (
        0.1 * np.sin(6 * x) * np.cos(5 * y)
        + 0.05 * np.sin(17 * x + 3 * y)
        + 0.04 * np.cos(13 * y - 7 * x)
        + 0.2 * x * x
    )
    dzx = (
        0.6 * np.cos(6 * x) * np.cos(5 * y)
        + 0.85 * np.cos(17 * x + 3 * y)
        + 0.28 * np.sin(13 * y - 7 * x)
        + 0.4 * x
    )
    dzy = (
        -0.5 * np.sin(6 * x) * np.sin(5 * y)
        + 0.15 * np.cos(17 * x + 3 * y)
        - 0.52 * np.sin(13 * y - 7 * x)
    )
    nrm = np.c_[-dzx, -dzy, np.ones(n)]
    return np.c_[xy, z], nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def random_rigid(rng):
    """A random proper rotation (3, 3) and translation (3,)."""
    a, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(a) < 0:
        a[:, 0] = -a[:, 0]
    return a, rng.normal(size=3)


def bumpy_sphere(n, seed):
    """n points on a closed bumpy surface of radius ~1 m with no symmetry (local frames are well defined)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    theta = np.arccos(u[:, 2])
    phi = np.arctan2(u[:, 1], u[:, 0])
    r = (
        1.0
        + 0.18 * np.sin(3 * theta) * np.cos(2 * phi)
        + 0.1 * np.cos(5 * theta + phi)
        + 0.06 * np.sin(7 * phi)
    )
    return u * r[:, None]


def corresponding_vs_random(describe, surface_seed, rng_seed, n_keypoints):
    """Descriptor distances of corresponding keypoints and of random pairs (medians, in that order).

    The surface is moved rigidly with 0.1 mm of noise; ``describe(points, normals, keypoints)``.
    """
    pts, nrm = surface(seed=surface_seed)
    rng = np.random.default_rng(rng_seed)
    rot, t = random_rigid(rng)
    moved = (pts + rng.normal(scale=1e-4, size=pts.shape)) @ rot.T + t
    kps = rng.choice(len(pts), n_keypoints, replace=False)
    a = describe(pts, nrm, kps)
    b = describe(moved, nrm @ rot.T, kps)
    corr = np.linalg.norm(a - b, axis=1)
    rand = np.linalg.norm(a - b[rng.permutation(len(kps))], axis=1)
    return np.median(corr), np.median(rand)
