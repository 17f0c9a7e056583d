"""IMU integration benchmark: time per 100-sample batch (0.5 s at 200 Hz), and accuracy figures.

Timing: median of many runs of
  - atr.imu.integrate (public call: validation + numba kernel + NavState),
  - the numba strapdown kernel alone,
  - PoseIntegrator.add_imu + camera_pose (what the service does per batch and frame),
  - reference: the same midpoint/trapezoid scheme written as a plain scipy Rotation loop.
Accuracy (with --accuracy): EuRoC V1_01_easy windows (strapdown and literal paper eq. 4), the
numbers in docs/imu.md.

Run: ./dev bench imu [--accuracy]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from atr.imu import ImuConfig, NavState, PoseIntegrator, integrate
from atr.imu._kernels import strapdown_kernel

N_SAMPLES = 100
PERIOD_NS = 5_000_000
REPEATS = 2000
SHARED = Path(__file__).resolve().parents[1] / ".." / "shared"


def _batch(seed: int = 0):
    rng = np.random.default_rng(seed)
    t = (np.arange(1, N_SAMPLES + 1) * PERIOD_NS).astype(np.int64)
    gyro = rng.normal(scale=0.5, size=(N_SAMPLES, 3))
    accel = rng.normal(scale=1.0, size=(N_SAMPLES, 3)) + [0.0, 0.0, 9.81]
    return t, gyro, accel


def _scipy_loop(state: NavState, t_ns, gyro, accel, g):
    """Reference: one scipy Rotation per sample, the kernel's scheme minus the coning term."""
    R = Rotation.from_matrix(state.R_world_imu)
    p, v = state.p_world_m.copy(), state.v_world_mps.copy()
    t = np.concatenate(([state.stamp_ns], t_ns))
    w = np.vstack((gyro[:1], gyro)) - state.gyro_bias_radps
    f = np.vstack((accel[:1], accel)) - state.accel_bias_mps2
    a_prev = R.apply(f[0]) + g
    for k in range(len(t) - 1):
        h = (t[k + 1] - t[k]) * 1e-9
        R = R * Rotation.from_rotvec(0.5 * h * (w[k] + w[k + 1]))
        a_next = R.apply(f[k + 1]) + g
        p = p + h * v + h * h * (2.0 * a_prev + a_next) / 6.0
        v = v + 0.5 * h * (a_prev + a_next)
        a_prev = a_next
    return R.as_matrix(), p, v


def _median_us(fn, repeats: int) -> float:
    times = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter_ns()
        fn()
        times[i] = time.perf_counter_ns() - t0
    return float(np.median(times)) / 1e3


def bench_timing() -> None:
    cfg = ImuConfig()
    cfg_paper = ImuConfig(integration="paper")
    s0 = NavState.at_rest(0)
    t, gyro, accel = _batch()
    integrate(s0, t, gyro, accel, config=cfg)  # compile / load the JIT cache
    n = N_SAMPLES + 1
    R0, dt = np.eye(3), np.full(N_SAMPLES, PERIOD_NS * 1e-9)
    g_full, a_full = np.vstack((gyro[:1], gyro)), np.vstack((accel[:1], accel))
    qo, po, vo, Ro = np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3)), np.empty((3, 3))
    z3, gw = np.zeros(3), cfg.gravity_world_mps2

    def kernel():
        strapdown_kernel(R0, z3, z3, z3, z3, gw, dt, g_full, a_full, qo, po, vo, Ro)

    def per_frame():
        pi = PoseIntegrator(cfg, s0)
        pi.add_imu(t, gyro, accel)
        pi.camera_pose(int(t[-1]) - PERIOD_NS // 2)

    results = {
        "integrate() (validation + numba kernel)": _median_us(
            lambda: integrate(s0, t, gyro, accel, config=cfg), REPEATS),
        "numba strapdown kernel alone": _median_us(kernel, REPEATS),
        "PoseIntegrator add_imu + camera_pose": _median_us(per_frame, REPEATS),
        "integrate(), paper eqs. (3)-(4)": _median_us(
            lambda: integrate(s0, t, gyro, accel, config=cfg_paper), REPEATS),
        "reference: scipy Rotation loop": _median_us(
            lambda: _scipy_loop(s0, t, gyro, accel, gw), REPEATS // 10),
    }  # fmt: skip
    ref = results["reference: scipy Rotation loop"]
    print(
        f"# {N_SAMPLES}-sample batch at 200 Hz, median of {REPEATS} runs "
        f"(reference {REPEATS // 10})"
    )
    print("| path | median us | vs scipy loop |")
    print("|---|---:|---:|")
    for name, us in results.items():
        print(f"| {name} | {us:.1f} | {ref / us:.1f}x faster |")
    # the reference must agree with the kernel (same scheme, no coning term): a sanity check
    R_ref, p_ref, _ = _scipy_loop(s0, t, gyro, accel, gw)
    s1 = integrate(s0, t, gyro, accel, config=cfg)
    dR = Rotation.from_matrix(R_ref.T @ s1.R_world_imu).magnitude()
    print(
        f"kernel vs reference after {N_SAMPLES} samples: {np.degrees(dR):.2e} deg, "
        f"{np.linalg.norm(p_ref - s1.p_world_m):.2e} m (coning term only)"
    )


def bench_accuracy() -> None:
    from atr.imu.evaluate import error_bound, ground_truth_errors, window_errors
    from atr.io.euroc import read_groundtruth, read_imu, read_imu_noise

    root = SHARED / "data" / "euroc_v1_01_easy_micro"
    if not (root / "mav0" / "imu0" / "data.csv").is_file():
        print(f"EuRoC data absent at {root}: accuracy skipped")
        return
    imu = read_imu(root)
    gt = read_groundtruth(root / "groundtruth" / "V1_01_easy.csv")
    noise = read_imu_noise(root)
    moved = np.linalg.norm(gt.p_world_m - gt.p_world_m[0], axis=1) > 0.005
    ge = ground_truth_errors(imu, gt, int(gt.t_ns[int(np.argmax(moved)) - 1]))
    print(f"\nground truth at rest: {ge}")
    starts = np.nonzero(np.linalg.norm(gt.v_world_mps, axis=1) > 0.2)[0][::5]
    print(
        "| mode | window s | n | rot median / p90 / max deg | trans median / p90 / max m "
        "| bound rot deg | bound trans m | GT distance median m |"
    )
    print("|---|---:|---:|---|---|---:|---:|---:|")
    for mode in ("strapdown", "paper"):
        for w in (0.05, 0.5, 1.0):
            cfg = ImuConfig(integration=mode)
            e = window_errors(imu, gt, starts, w, config=cfg)
            rb, tb = error_bound(w, noise.gyro_noise_density, noise.accel_noise_density, ge,
                                 cfg.gravity_mps2)  # fmt: skip
            r = np.degrees(np.percentile(e.rotation_error_rad, [50, 90, 100]))
            tr = np.percentile(e.translation_error_m, [50, 90, 100])
            print(
                f"| {mode} | {w} | {len(e.start_ns)} | {r[0]:.4f} / {r[1]:.4f} / {r[2]:.4f} "
                f"| {tr[0]:.4f} / {tr[1]:.4f} / {tr[2]:.4f} | {np.degrees(rb):.4f} | {tb:.4f} "
                f"| {np.median(e.gt_distance_m):.3f} |"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--accuracy", action="store_true", help="also print EuRoC accuracy figures")
    a = parser.parse_args()
    bench_timing()
    if a.accuracy:
        bench_accuracy()


if __name__ == "__main__":
    main()
