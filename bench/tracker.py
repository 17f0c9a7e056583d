"""Tracker benchmark: time of one `Tracker.update` per scene (what services/tracker adds per scene).

A flight of 200 scenes, one orbit at 80 m: one target seen with 0.4 m noise in 80 % of them, and
`--clutter` false positives per scene scattered over 200 m (every one starts a tentative track); each
detection carries its scene's viewpoint, as the services' do. The time is the median over the
scenes of the median over `--repeats` replays of the whole flight. With `--set tracking.FIELD=VALUE`,
the same flight also runs with those settings, interleaved with the defaults in this process, and the
ratio of the two is printed.

Run: ./dev bench tracker [--clutter 3] [--repeats 7] [--set tracking.fuse_median=false]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from atr.config import load_config
from atr.tracking import Tracker, TrackingConfig, TrackInput

SCENES = 200
STEP_NS = 500_000_000


def flight(clutter: int, seed: int = 0) -> list[list[TrackInput]]:
    rng = np.random.default_rng(seed)
    target = np.array([12.0, -7.0, 0.0])
    scenes = []
    for k in range(SCENES):
        a = 2 * np.pi * k / SCENES
        viewpoint = target + 80.0 * np.array([np.cos(a), np.sin(a), 0.5])
        ds = []
        if rng.random() < 0.8:
            p = target + rng.normal(0, 0.4, 3)
            ds.append(TrackInput("t72", p, 0.7 + rng.normal(0, 0.1), 1.0, viewpoint))
        for _ in range(clutter):
            p = rng.uniform(-100, 100, 3) * [1, 1, 0]
            ds.append(TrackInput("t72", p, rng.uniform(-np.pi, np.pi), 1.0, viewpoint))
        scenes.append(ds)
    return scenes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--clutter", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    scenes = flight(args.clutter)
    configs = {"defaults": TrackingConfig()}
    if args.overrides:
        configs[" ".join(args.overrides)] = load_config(None, args.overrides).tracking
    times_ms = {label: np.zeros((args.repeats, SCENES)) for label in configs}
    live = {}
    for r in range(args.repeats):
        for label, config in configs.items():  # interleaved: both see the same machine load
            tracker = Tracker(config)
            for k, ds in enumerate(scenes):
                t0 = time.perf_counter()
                tracks = tracker.update(ds, 1_000_000_000 + k * STEP_NS)
                times_ms[label][r, k] = 1e3 * (time.perf_counter() - t0)
            live[label] = len(tracks)
    medians = {}
    for label, t in times_ms.items():
        per_scene = np.median(t, axis=0)
        medians[label] = float(np.median(per_scene))
        print(
            f"tracker ({label}): {args.clutter} clutter detections/scene, {live[label]} live tracks at "
            f"the end: median {medians[label]:.3f} ms/scene, p95 {np.percentile(per_scene, 95):.3f} ms "
            f"({args.repeats} runs of {SCENES} scenes)"
        )
    for label in list(configs)[1:]:
        print(f"{label} / defaults: {medians[label] / medians['defaults']:.2f} x")


if __name__ == "__main__":
    main()
