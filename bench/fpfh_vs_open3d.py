"""FPFH speed: ours (atr.features3d._fpfh) against Open3D's compute_fpfh_feature, same cloud, same run.

Prints the median of several runs and the ratio ours / Open3D (goal <= 1.5) for 2,000 keypoints on a
20,000-point cloud, then every descriptor of this module set (FPFH, RoPS, HoD, HoD-S) for 1,000 keypoints on a
10,000-point cloud on one core, and numba's first-call time (cache load, or compile when the cache is cold).
Usage: ./dev bench fpfh_vs_open3d
"""

from __future__ import annotations

import statistics
import time

import numba
import numpy as np
import open3d as o3d

from atr.features3d._fpfh import fpfh
from atr.features3d._hod import hod
from atr.features3d._rops import rops

RUNS = 7
RHO = 8.0  # radius = RHO × mean nearest-neighbour spacing (~50 neighbours)


def bumpy_surface(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 1, (n, 2))
    x, y = xy[:, 0], xy[:, 1]
    z = 0.1 * np.sin(6 * x) * np.cos(5 * y) + 0.05 * np.sin(17 * x + 3 * y)
    dzx = 0.6 * np.cos(6 * x) * np.cos(5 * y) + 0.85 * np.cos(17 * x + 3 * y)
    dzy = -0.5 * np.sin(6 * x) * np.sin(5 * y) + 0.15 * np.cos(17 * x + 3 * y)
    nrm = np.c_[-dzx, -dzy, np.ones(n)]
    return np.c_[xy, z], nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def median_ms(f) -> float:
    times = []
    for _ in range(RUNS):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times)


def spacing(pts: np.ndarray) -> float:
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    return float(np.mean(pc.compute_nearest_neighbor_distance()))


def main() -> None:
    pts, nrm = bumpy_surface(20_000, 0)
    kps = np.random.default_rng(1).choice(len(pts), 2000, replace=False)
    radius = RHO * spacing(pts)

    t = time.perf_counter()
    fpfh(pts[:100], nrm[:100], np.arange(10), radius)
    rops(pts[:100], np.arange(10), radius)
    hod(pts[:100], np.arange(10), radius)
    print(f"numba first call (cache load or compile): {time.perf_counter() - t:.2f} s")

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.normals = o3d.utility.Vector3dVector(nrm)
    param = o3d.geometry.KDTreeSearchParamRadius(radius)
    idx = o3d.utility.IntVector(kps.tolist())
    for threads in (numba.config.NUMBA_NUM_THREADS, 1):
        numba.set_num_threads(threads)
        ours = median_ms(lambda: fpfh(pts, nrm, kps, radius))
        theirs = median_ms(lambda: o3d.pipelines.registration.compute_fpfh_feature(pc, param, idx))
        print(
            f"FPFH 2000 kp / 20000 pts, radius {radius:.4f} m, numba threads {threads}: ours {ours:.1f} ms, "
            f"Open3D {theirs:.1f} ms, ratio {ours / theirs:.2f}"
        )

    numba.set_num_threads(1)
    pts, nrm = bumpy_surface(10_000, 2)
    kps = np.random.default_rng(3).choice(len(pts), 1000, replace=False)
    radius = RHO * spacing(pts)
    for name, f in [
        ("fpfh", lambda: fpfh(pts, nrm, kps, radius)),
        ("rops (point-based LRF)", lambda: rops(pts, kps, radius)),
        ("hod", lambda: hod(pts, kps, radius)),
        ("hod-s", lambda: hod(pts, kps, radius, short=True)),
    ]:
        f()
        print(
            f"{name}: 1000 kp / 10000 pts, radius {radius:.4f} m, one core: {median_ms(f):.1f} ms"
        )


if __name__ == "__main__":
    main()
