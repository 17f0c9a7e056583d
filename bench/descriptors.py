"""Time every 3D descriptor: 1,000 keypoints on a 10,000-point sampled surface, one core.

Prints a table: first call in a fresh process (includes loading the numba cache from disk, or compiling when the
cache is cold) and the median of the following runs; also Open3D's C++ FPFH on the same input as a reference,
and the FPFH goal of the issue (2,000 keypoints on 20,000 points, ours ≤ 1.5x Open3D). Descriptors whose module
is not in the checkout are skipped.

    NUMBA_NUM_THREADS=1 NUMBA_CACHE_DIR=.numba_cache .venv/bin/python bench/descriptors.py [--runs 7]
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # the goal is stated for one core
os.environ.setdefault("OMP_NUM_THREADS", "1")  # Open3D's reference FPFH on one core too

import numpy as np  # noqa: E402

from atr.features3d import DESCRIPTOR_NAMES, describe, estimate_normals, is_available  # noqa: E402
from cli._args import script_parser  # noqa: E402

# the closed bumpy surface of the descriptor property tests
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "features3d"))
from _surfaces import bumpy_sphere  # noqa: E402


def resolution(points: np.ndarray) -> float:
    from scipy.spatial import cKDTree

    d, _ = cKDTree(points).query(points, k=2)
    return float(d[:, 1].mean())


def time_call(fn, runs: int) -> tuple[float, float, float]:
    """First-call wall time, then median wall and median CPU time of ``runs`` further calls, seconds.

    CPU time (process_time) is reported too because a shared machine inflates wall time; with one numba thread
    and one Open3D thread the two agree on an idle machine.
    """
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    wall, cpu = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return first, float(np.median(wall)), float(np.median(cpu))


def open3d_fpfh(points: np.ndarray, normals: np.ndarray, keypoints: np.ndarray, radius: float):
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.normals = o3d.utility.Vector3dVector(normals)
    param = o3d.geometry.KDTreeSearchParamRadius(radius)
    if hasattr(o3d.pipelines.registration, "compute_fpfh_feature"):
        try:
            return o3d.pipelines.registration.compute_fpfh_feature(
                pcd, param, indices=o3d.utility.IntVector(keypoints.tolist())
            )
        except TypeError:  # older Open3D: no index subset, describe all points
            return o3d.pipelines.registration.compute_fpfh_feature(pcd, param)
    raise RuntimeError("Open3D has no compute_fpfh_feature")


def main() -> None:
    ap = script_parser(__doc__)
    ap.add_argument("--runs", type=int, default=7, help="timed calls per descriptor (median)")
    ap.add_argument("--points", type=int, default=10_000, help="points of the sampled surface")
    ap.add_argument("--keypoints", type=int, default=1_000, help="points described")
    args = ap.parse_args()

    pts = bumpy_sphere(args.points, seed=1)
    res = resolution(pts)
    radius = 5 * res
    t0 = time.perf_counter()
    normals = estimate_normals(pts, k=6)
    t_normals = time.perf_counter() - t0
    kp = np.random.default_rng(2).choice(args.points, args.keypoints, replace=False)
    from atr.features3d._neighbours import RadiusSearch

    nb = RadiusSearch(pts, radius).count(pts[kp]).mean()
    print(
        f"cloud {args.points} pts, resolution {res * 1000:.1f} mm, radius {radius * 1000:.1f} mm (5x), "
        f"~{nb:.0f} neighbours/keypoint, {args.keypoints} keypoints, NUMBA_NUM_THREADS="
        f"{os.environ['NUMBA_NUM_THREADS']}"
    )
    print(f"normals (k=6, all points, first call): {t_normals * 1000:.1f} ms")
    t_n = time_call(lambda: estimate_normals(pts, k=6), args.runs)
    print(f"normals median: {t_n[1] * 1000:.1f} ms wall, {t_n[2] * 1000:.1f} ms CPU\n")
    print(
        "| descriptor | length | first call in process (ms) | median wall (ms) | median CPU (ms) | CPU <= 100 ms |"
    )
    print("|---|---|---|---|---|---|")
    for name in DESCRIPTOR_NAMES:
        if not is_available(name):
            print(f"| {name} | - | not implemented yet | - | - |")
            continue
        fn = lambda name=name: describe(name, pts, normals, kp, radius)  # noqa: E731
        first, med, cpu = time_call(fn, args.runs)
        length = fn().shape[1]
        print(
            f"| {name} | {length} | {first * 1000:.1f} | {med * 1000:.1f} | {cpu * 1000:.1f} | "
            f"{'yes' if cpu <= 0.1 else 'NO'} |"
        )
    _, o3d_med, o3d_cpu = time_call(lambda: open3d_fpfh(pts, normals, kp, radius), args.runs)
    print(
        f"| Open3D FPFH (C++, reference) | 33 | - | {o3d_med * 1000:.1f} | {o3d_cpu * 1000:.1f} | - |"
    )

    # The FPFH goal of the issue: 2,000 keypoints on 20,000 points against Open3D on the same input.
    if is_available("fpfh"):
        pts2 = bumpy_sphere(20_000, seed=3)
        r2 = 5 * resolution(pts2)
        n2 = estimate_normals(pts2, k=6)
        kp2 = np.random.default_rng(4).choice(len(pts2), 2_000, replace=False)
        _, _, ours = time_call(lambda: describe("fpfh", pts2, n2, kp2, r2), args.runs)
        _, _, ref = time_call(lambda: open3d_fpfh(pts2, n2, kp2, r2), args.runs)
        print(
            f"\nFPFH 2,000 keypoints / 20,000 points (CPU): ours {ours * 1000:.1f} ms, Open3D "
            f"{ref * 1000:.1f} ms, ratio {ours / ref:.2f} (goal <= 1.5)"
        )


if __name__ == "__main__":
    main()
