"""Time per matcher stage per descriptor on an SfM-like cloud (~10k points) and a LIDAR-like cloud (~260k).

Prints the median of several runs per stage, and the total as a ratio to a fixed numpy reference workload
timed in the same process (so figures compare across machines).

    python bench/matcher.py [--runs 3] [--descriptors shot fpfh ...] [--clouds sfm lidar] [--scene FILE.npz]
                            [--targets t72 ifv truck6x6]

With ``--scene``, the clouds are a simulated scene written by ``bench/tune_recognition.py make`` (its SfM
cloud, its LIDAR cloud when present, and the camera position), matched against the templates of
``--targets`` as the matcher service does; otherwise synthetic clouds from ``atr.recognition.synthetic``.
Set OPENBLAS_NUM_THREADS=1 on a shared machine: BLAS threads fighting for busy cores inflate the times.
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

from atr.evaluation.timing import REFERENCE_WORKLOAD, reference_workload_ms
from atr.recognition import STAGES, RecognitionConfig, build_template, recognize
from atr.recognition import synthetic as syn
from atr.recognition._backend import have_descriptor


def _clouds(mesh) -> dict[str, np.ndarray]:
    T = syn.pose(0.0, -2.0, 0.7)
    veh = [((mesh.vertices, mesh.triangles), T)]
    # SfM-like: sparse, noisy, concentrated around the target (GFTT/KLT ~10k points, paper §III-D-3).
    sfm = syn.aerial_scene(veh, seed=1, extent_m=15, n_clutter=3, samples_per_m2=12, noise_m=0.1)
    # LIDAR-like: dense and wide (~260k points).
    lidar = syn.aerial_scene(
        veh, seed=2, extent_m=45, n_clutter=20, samples_per_m2=45, noise_m=0.03
    )
    return {"sfm": sfm, "lidar": lidar}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument(
        "--descriptors", nargs="+", default=["hod-s", "hod", "fpfh", "shot", "rops", "usc", "3dsc"]
    )
    ap.add_argument("--clouds", nargs="+", default=["sfm", "lidar"])
    ap.add_argument(
        "--scene", default="", help="a tuning-set .npz (bench/tune_recognition.py make)"
    )
    ap.add_argument("--targets", nargs="+", default=["t72"])
    args = ap.parse_args()
    from atr.sim.vehicles import VEHICLES, t72

    mesh = t72()
    viewpoint = None
    truth_xy = np.array([0.0, -2.0])
    if args.scene:
        with np.load(args.scene) as z:
            clouds = {"sfm": z["sfm_points_m"].astype(np.float64)}
            if "lidar_points_m" in z.files:
                clouds["lidar"] = z["lidar_points_m"].astype(np.float64)
            viewpoint = z["viewpoint_m"]
            truth_xy = z["T_world_target"][:2, 3]
        clouds = {k: v for k, v in clouds.items() if k in args.clouds}
    else:
        clouds = _clouds(mesh)
    ref = reference_workload_ms()
    print(f"reference ({REFERENCE_WORKLOAD}): {ref:.1f} ms")
    print(
        "cloud  points  descriptor "
        + " ".join(f"{s:>9}" for s in STAGES)
        + "     total  x ref  found"
    )
    for name in args.clouds:
        if name not in clouds:  # a tuning scene made without its LIDAR scan
            print(f"{name:5} not in {args.scene}")
            continue
        pts = clouds[name]
        for desc in args.descriptors:
            if not have_descriptor(desc):
                print(f"{name:5} {len(pts):7d}  {desc:10} not available")
                continue
            cfg = RecognitionConfig(descriptor=desc)
            try:
                tpls = [
                    build_template(VEHICLES[t]().vertices, VEHICLES[t]().triangles, t, desc, cfg)
                    for t in args.targets
                ]
            except Exception as exc:  # noqa: BLE001 - a missing descriptor must not stop the bench
                print(f"{name:5} {len(pts):7d}  {desc:10} failed: {exc}")
                continue
            recognize(pts, tpls, cfg, seed=0, viewpoint_m=viewpoint)  # warm-up (JIT)
            runs = [
                recognize(pts, tpls, cfg, seed=0, viewpoint_m=viewpoint) for _ in range(args.runs)
            ]
            med = {
                s: statistics.median(r.stage_times_ms[s] for r in runs) for s in (*STAGES, "total")
            }
            found = any(
                d.target == "t72" and np.linalg.norm(d.T_world_target[:2, 3] - truth_xy) < 2
                for d in runs[0].detections
            )
            print(
                f"{name:5} {len(pts):7d}  {desc:10} "
                + " ".join(f"{med[s]:9.1f}" for s in STAGES)
                + f" {med['total']:9.1f} {med['total'] / ref:6.1f}  {found}",
                flush=True,
            )


if __name__ == "__main__":
    main()
