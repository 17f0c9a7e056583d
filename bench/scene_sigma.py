"""The SfM cloud's position uncertainty (sigma) on the target, by run: what `recognition.k_plane_sigma` gates.

Renders frame pairs spread along each run as the tuning set does (``tune_recognition.py make``: the same
world, orbit and renderer), reconstructs them with the dense matcher (the `sgm-sfm` arm) on the true poses,
and prints per run the median sigma of the cloud's points within the target's reach of its position (the
points ICP fits there), as metres and as a multiple of the recognition resolution.
Prints figures; asserts nothing.

    python bench/scene_sigma.py [--seed 101] [--runs 1-1 1-4 2-1 2-4] [--pairs 3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from tune_recognition import _render_pair  # noqa: E402

from atr.recognition import RecognitionConfig  # noqa: E402
from atr.sfm import SfmConfig, reconstruct  # noqa: E402
from atr.sim.config import SimConfig  # noqa: E402
from atr.sim.scenarios import scenario  # noqa: E402
from atr.sim.world import build_world  # noqa: E402

TARGET_REACH_M = (
    5.0  # the T-72's half length plus the ICP gate: the points a fit there can pair with
)


def main() -> None:
    """Parse, reconstruct each run's pairs, print the median sigma on the target."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seed", type=int, default=101)
    parser.add_argument("--runs", nargs="+", default=["1-1", "1-4", "2-1", "2-4"])
    parser.add_argument("--pairs", type=int, default=3, help="frame pairs per run")
    args = parser.parse_args()
    sim, sfm = SimConfig(), SfmConfig(matcher="sgm")
    resolution_m = RecognitionConfig().resolution_m
    for name in args.runs:
        s, r = (int(x) for x in name.split("-"))
        scen = scenario(s, r)
        world = build_world(scen, args.seed, config=sim)
        target_m = world.T_world_target[:3, 3]
        medians = []
        for p in range(args.pairs):
            seq_a = int(p / args.pairs * (scen.n_frames - sfm.pair_gap_frames - 1))
            (img_a, T_a, _, _), (img_b, T_b, _, _) = _render_pair(
                world, scen, seq_a, sfm.pair_gap_frames, False, args.seed, sim
            )
            cloud = reconstruct(img_a, img_b, sim.K, T_a, T_b, sfm)
            near = np.linalg.norm(cloud.points_world_m - target_m, axis=1) <= TARGET_REACH_M
            if near.any():
                medians.append(float(np.median(cloud.sigma_m[near])))
        if not medians:
            print(
                f"run {name} ({scen.range_m:.0f} m, {scen.obliquity_deg:.0f} deg): no point on the target"
            )
            continue
        m = float(np.median(medians))
        print(
            f"run {name} ({scen.range_m:.0f} m, {scen.obliquity_deg:.0f} deg): median sigma on the target "
            f"{m:.3f} m = {m / resolution_m:.2f} x resolution (pairs: "
            f"{' '.join(f'{x:.3f}' for x in medians)})"
        )


if __name__ == "__main__":
    main()
