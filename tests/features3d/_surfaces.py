"""Test geometry shared by the descriptor property tests: a smooth surface with exact normals, rigid motions."""

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
