"""Simulator speed: world build, frames/s at 1280x960, LIDAR rays/s, projected time for the Table II
set.

Usage:
    python bench/sim.py                   # figures (median of several runs)
    python bench/sim.py --pictures DIR    # also write the documentation pictures into DIR

The reference run (same process, same ray count) is Open3D's cast_rays on a one-box scene: it shows
the raw ray-casting cost of this machine at this moment, so figures from a loaded machine can be
compared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
import open3d as o3d

from atr.sim import SimConfig, all_scenarios, build_world, scenario, simulate_flight
from atr.sim.mesh import box
from atr.sim.render import Renderer, project, to_srgb8
from atr.sim.visibility import raycasting_scene


def _median_time(fn, repeat: int, clock=time.perf_counter) -> float:
    ts = []
    for _ in range(repeat):
        t = clock()
        fn()
        ts.append(clock() - t)
    return statistics.median(ts)


def figures(repeat: int) -> None:
    cfg = SimConfig()
    print(f"load average at start: {os.getloadavg()[0]:.2f} (2 cores)")
    n_rays = cfg.width_px * cfg.height_px
    ref_scene, _ = raycasting_scene([box((2, 2, 2), (0, 0, 0))])
    rays = np.zeros((n_rays, 6), np.float32)
    rays[:, 3:] = np.random.default_rng(0).normal(size=(n_rays, 3))
    ref_scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
    t_ref = _median_time(lambda: ref_scene.cast_rays(o3d.core.Tensor.from_numpy(rays)), repeat)
    cpu_ref = _median_time(
        lambda: ref_scene.cast_rays(o3d.core.Tensor.from_numpy(rays)), repeat, time.process_time
    )
    print(
        f"reference: cast_rays on a one-box scene, {n_rays} rays: {t_ref * 1e3:.0f} ms "
        f"({cpu_ref:.2f} CPU s)"
    )
    per_run = {}
    for sc in (scenario(1, 3), scenario(2, 3), scenario(3, 1)):
        t = time.perf_counter()
        world = build_world(sc, 0, config=cfg)
        t_world = time.perf_counter() - t
        ren = Renderer(world, cfg)
        T = world.orbit.T_world_imu(0.0) @ cfg.T_imu_cam_matrix
        ren.render(T)  # JIT warm-up and BVH build
        t_frame = _median_time(lambda: ren.render(T), repeat)
        cpu_frame = _median_time(lambda: ren.render(T), repeat, time.process_time)
        t_vis = _median_time(lambda: ren.visible_fraction(T), repeat)
        lrng = np.random.default_rng(0)
        ren.lidar_scan(T, sc.lidar_resolution_m, sc.range_m, lrng)
        t_lidar = _median_time(
            lambda: ren.lidar_scan(T, sc.lidar_resolution_m, sc.range_m, lrng), repeat
        )
        lidar_rays = cfg.lidar_grid**2 * (cfg.lidar_sub_rays + 1)
        it = simulate_flight(sc, seed=0, frames=repeat + 1, config=cfg, world=world)
        next(it)
        t = time.perf_counter()
        n = sum(1 for _ in it)
        t_sim = (time.perf_counter() - t) / max(n, 1)
        per_run[sc.scenario] = (t_world, t_sim, t_lidar)
        print(
            f"scenario {sc.scenario} run {sc.run} ({sc.range_m:.0f} m, "
            f"{sc.obliquity_deg:.0f} deg): "
            f"world build {t_world:.2f} s ({world.static.n_triangles} triangles); "
            f"render {t_frame * 1e3:.0f} ms/frame = {1 / t_frame:.2f} frames/s "
            f"({t_frame / t_ref:.1f}x reference, {cpu_frame:.2f} CPU s); "
            f"visible_fraction {t_vis * 1e3:.0f} ms; "
            f"simulate_flight {t_sim * 1e3:.0f} ms/frame; "
            f"LIDAR scan {t_lidar * 1e3:.0f} ms = {lidar_rays / t_lidar / 1e6:.2f} M rays/s"
        )
    total_cam = total_lidar = 0.0
    for sc in all_scenarios():
        t_world, t_sim, t_lidar = per_run[sc.scenario]
        total_cam += t_world + sc.n_frames * t_sim
        total_lidar += sc.n_frames * t_lidar
    print(
        f"projected Table II set (9 runs, {sum(s.n_frames for s in all_scenarios())} frames): "
        f"{total_cam / 60:.1f} min camera+IMU+truth, +{total_lidar / 60:.1f} min with LIDAR"
    )


# pictures -----------------------------------------------------------------------------------------


def _bgr(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_RGB2BGR)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    out = img.copy()
    cv2.rectangle(out, (0, 0), (8 + 11 * len(text), 26), (0, 0, 0), -1)
    cv2.putText(out, text, (5, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    z = target - eye
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = eye
    return T


def pictures(out: Path, seed: int) -> None:
    out.mkdir(parents=True, exist_ok=True)
    cfg = SimConfig()
    tiles = []
    for sc in all_scenarios():
        f = next(simulate_flight(sc, seed=seed, frames=1, config=cfg))
        name = f"frame_s{sc.scenario}_r{sc.run}.png"
        if (sc.scenario, sc.run) in ((1, 3), (3, 1)):
            cv2.imwrite(str(out / name), _bgr(f.image))
        small = cv2.resize(f.image, (480, 360), interpolation=cv2.INTER_AREA)
        text = f"scenario {sc.scenario}: {sc.range_m:.0f} m, {sc.obliquity_deg:.0f} deg"
        tiles.append(_label(small, text))
        print(f"{name}: visible_fraction {f.targets[0].visible_fraction:.2f}")
    while len(tiles) % 3:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[i : i + 3]) for i in range(0, len(tiles), 3)]
    cv2.imwrite(str(out / "frames_table2.png"), _bgr(np.vstack(rows)))
    # KLT tracks between the two frames of a scene (GFTT + pyramidal LK, forward-backward check 1
    # px)
    sc = scenario(2, 3)
    f0, f1 = list(simulate_flight(sc, seed=seed, frames=2, config=cfg))
    g0, g1 = (cv2.cvtColor(f.image, cv2.COLOR_RGB2GRAY) for f in (f0, f1))
    p0 = cv2.goodFeaturesToTrack(g0, 20000, 1e-3, 3, blockSize=3)
    p1, st, _ = cv2.calcOpticalFlowPyrLK(g0, g1, p0, None, winSize=(11, 11), maxLevel=12)
    pb, st2, _ = cv2.calcOpticalFlowPyrLK(g1, g0, p1, None, winSize=(11, 11), maxLevel=12)
    ok = (st.ravel() == 1) & (st2.ravel() == 1) & (np.linalg.norm(pb - p0, axis=2).ravel() < 1.0)
    vis = _bgr(f1.image)
    for a, b in zip(p0[ok].reshape(-1, 2), p1[ok].reshape(-1, 2), strict=True):
        a_px, b_px = tuple(np.round(a).astype(int)), tuple(np.round(b).astype(int))
        cv2.line(vis, a_px, b_px, (0, 255, 255), 1)
    vis = _label(vis, f"GFTT {len(p0)} corners, KLT tracked {int(ok.sum())} (fb < 1 px)")
    cv2.imwrite(str(out / "klt_tracks_s2_r3.png"), vis)
    print(f"KLT: {len(p0)} corners, {int(ok.sum())} tracked")
    # LIDAR cloud of scenario 3 (200 m), seen obliquely from a virtual camera, coloured by height
    sc = scenario(1, 3)
    f = next(simulate_flight(sc, seed=seed, frames=1, config=cfg, lidar=True))
    pts = f.lidar_points_m
    tgt = f.targets[0].T_world_target[:3, 3]
    eye = tgt + np.array([-22.0, -30.0, 26.0])
    Tv = _look_at(eye, tgt + [0, 0, 1.0])
    K = np.array([[1100.0, 0, 639.5], [0, 1100.0, 479.5], [0, 0, 1]])
    uv = project(pts, K, Tv)
    depth = np.linalg.norm(pts - eye, axis=1)
    order = np.argsort(-depth)
    canvas = np.full((960, 1280, 3), 20, np.uint8)
    z = pts[:, 2] - tgt[2]
    col = cv2.applyColorMap(
        np.clip((z + 0.5) / 8.0 * 255, 0, 255).astype(np.uint8)[:, None], cv2.COLORMAP_TURBO
    )
    for i in order:
        u, v = uv[i]
        if np.isfinite(u) and 0 <= u < 1280 and 0 <= v < 960:
            canvas[int(v), int(u)] = col[i, 0]
    canvas = _label(canvas, f"LIDAR scan, scenario 1 (50 m, 30 deg, 11 cm): {len(pts)} points")
    cv2.imwrite(str(out / "lidar_cloud_s1_r3.png"), canvas)
    # world overview from high above
    world = build_world(scenario(3, 1), seed, config=cfg)
    wide = SimConfig(width_px=1120, height_px=840, focal_px=610.0)
    ren = Renderer(world, wide)
    tgt = world.T_world_target[:3, 3]
    lin, _ = ren.render(_look_at(tgt + np.array([-260.0, -200.0, 330.0]), tgt))
    overview = _label(to_srgb8(lin), "world overview (scenario 3 world)")
    cv2.imwrite(str(out / "world_overview.png"), _bgr(overview))
    # the T-72 model, close up
    close = SimConfig(width_px=960, height_px=720, focal_px=1100.0)
    ren = Renderer(world, close)
    views = (("t72_three_quarter.png", [9.0, 8.0, 5.0]), ("t72_rear.png", [-11.0, 5.0, 4.5]))
    for name, off in views:
        R = world.T_world_target[:3, :3]
        lin, _ = ren.render(_look_at(tgt + R @ np.array(off), tgt + np.array([0, 0, 1.0])))
        cv2.imwrite(str(out / name), _bgr(_label(to_srgb8(lin), "T-72 model")))
    print(f"pictures written to {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=5, help="runs per figure (median)")
    parser.add_argument(
        "--pictures", type=Path, help="write documentation pictures into this folder"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-figures", action="store_true")
    args = parser.parse_args()
    if not args.no_figures:
        figures(args.repeat)
    if args.pictures:
        pictures(args.pictures, args.seed)


if __name__ == "__main__":
    main()
