"""Re-score the confirmed tracks of an evaluation's results with other tracker settings (no re-run).

The tracker runs offline over each run's stored detections, as `atr eval` does (`track_score`), once with
the defaults and once with `--set tracking.FIELD=VALUE` overrides; prints pooled TP / FP / FN of the
confirmed tracks per scene, track F1 and false confirmed tracks; with `--per-run`, each run's track F1,
scenes to first confirmation, false confirmed tracks and fused position error (the tracks issue's goals
are per run) beside the per-scene detections' median error and their mean offset in the target's frame
(along and across its heading, and up): an offset shared by a whole orbit is what fusing cannot remove.
Prints figures; asserts nothing. Example (the class votes of docs/tracking.md):

    python bench/track_rescore.py --results results --set tracking.class_votes=true [--per-run]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from atr.config import load_config  # noqa: E402
from atr.evaluation.io import load_run  # noqa: E402
from atr.evaluation.runner import Flight  # noqa: E402
from atr.evaluation.tables import track_score  # noqa: E402


def main() -> None:
    """Parse, load every run of the folder, score both ways, print."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--results", type=Path, required=True, help="an atr eval --results folder")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--per-run", action="store_true", help="also print each run's figures")
    args = parser.parse_args()
    base = load_config(None, [])
    other = load_config(None, args.overrides)
    runs = []
    for path in sorted((args.results / "runs").glob("*.json")):
        data = json.loads(path.read_text())
        flight = Flight(
            **{k: tuple(v) if isinstance(v, list) else v for k, v in data["flight"].items()}
        )
        records = load_run(path, data["key"])
        if records is not None:
            runs.append((flight, records))
    if not runs:
        parser.error(f"no result files under {args.results / 'runs'}")
    present = base.sim.present_min_visible_fraction
    for label, config in (("defaults", base), (" ".join(args.overrides) or "defaults", other)):
        tp = fp = fn = false_tracks = 0
        for flight, records in runs:
            score = track_score(records, flight.target, present, config.tracking)
            tp, fp, fn = tp + score.counts.tp, fp + score.counts.fp, fn + score.counts.fn
            false_tracks += score.false_tracks
            if args.per_run:
                c = score.counts
                print(
                    f"  {flight.target} {flight.scenario}-{flight.run} seed {flight.seed}: "
                    f"track F1 {2 * c.tp / max(1, 2 * c.tp + c.fp + c.fn):.3f}, "
                    f"confirmed after {score.scenes_to_confirm:g} scenes, "
                    f"{score.false_tracks} false tracks, "
                    f"fused T_error median {score.t_error_median_m:.2f} m; "
                    + _scene_errors(records, flight.target, present)
                )
        f1 = 2 * tp / max(1, 2 * tp + fp + fn)
        scenes = sum(len(r) for _, r in runs)
        print(
            f"{label}: track F1 {f1:.3f} (TP {tp} / FP {fp} / FN {fn}), "
            f"{false_tracks} false confirmed tracks in {scenes} scenes"
        )


def _scene_errors(records: Sequence, target: str, present: float) -> str:
    """Per scene: the best detection of the target within the 2 m bound, its error; the median, and
    the mean offset along and across the detected heading, and up."""
    errors, offsets = [], []
    for record in records:
        truth = [
            t for t in record.truth if t["name"] == target and t["visible_fraction"] >= present
        ]
        best = record.detections[0] if record.detections else None
        if not truth or best is None or best["target"] != target or "yaw_rad" not in best:
            continue
        e = np.asarray(record.sensor_relative(best["position_m"])) - truth[0]["position_m"]
        if np.linalg.norm(e) >= 2.0:
            continue
        yaw = record.sensor_relative_yaw(best["yaw_rad"])
        errors.append(float(np.linalg.norm(e)))
        offsets.append(
            (
                math.cos(yaw) * e[0] + math.sin(yaw) * e[1],
                -math.sin(yaw) * e[0] + math.cos(yaw) * e[1],
                e[2],
            )
        )
    if not errors:
        return "no per-scene TP"
    along, across, up = np.mean(offsets, axis=0)
    return (
        f"per scene median {np.median(errors):.2f} m, mean offset along {along:+.2f} / "
        f"across {across:+.2f} / up {up:+.2f} m"
    )


if __name__ == "__main__":
    main()
