"""The tables of an evaluation: each run's contract row and detailed row, and the results folder.

`rows` scores every (flight, arm) result (F1 counts, translation errors, times, what each false positive sits
on); `write_outputs` writes results/<timestamp>/ (results.json: the contract; details.json: per-run details for
`atr report`; config.json: the effective configuration) and points results/latest at it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from atr.config import to_dict
from atr.evaluation.experiment import Plan, storage_key
from atr.evaluation.io import jsonable
from atr.evaluation.metrics import TrackScore, score_tracks, vehicle_under
from atr.evaluation.runner import flight_world
from atr.evaluation.scoring import summarise
from atr.sim.scenarios import scenario as preset
from atr.tracking import Tracker, TrackingConfig, TrackInput

NOT_ON_A_VEHICLE = "elsewhere"


def flight_vehicles(flight: Any, sim_config: Any) -> tuple[list[str], Any, Any]:
    """The flight's non-target vehicles (names, (V, 3) positions, (V,) radii), from its world rebuilt
    without rendering (about a second; the same world `flight_frames` renders for it).
    """
    vehicles = flight_world(flight, sim_config).vehicles
    return (
        [v.name for v in vehicles],
        np.array([v.position_m for v in vehicles], np.float64).reshape(-1, 3),
        np.array([v.radius_m for v in vehicles], np.float64),
    )


def false_positives_on(
    records: Sequence[Any],
    outcomes: Sequence[str],
    target: str,
    vehicles: tuple[list[str], Any, Any],
) -> dict[str, int]:
    """How many of a run's false positives sit on each kind of non-target vehicle (its name), and how many
    on none (``NOT_ON_A_VEHICLE``: a building, a tree, the ground, or off the target).
    """
    counts: dict[str, int] = {}
    for record, outcome in zip(records, outcomes, strict=True):
        if outcome != "fp":
            continue
        best = max(
            (d for d in record.detections if d["target"] == target), key=lambda d: d["score"]
        )
        name = vehicle_under(record.sensor_relative(best["position_m"]), *vehicles)
        key = name or NOT_ON_A_VEHICLE
        counts[key] = counts.get(key, 0) + 1
    return counts


def track_score(
    records: Sequence[Any], target: str, present: float, config: TrackingConfig
) -> TrackScore:
    """Run the tracker (services/tracker's) over a run's scenes and judge its confirmed tracks.

    The detections enter the tracker as scoring sees them (`sensor_relative`: the pipeline's navigation
    drift is reported apart), with their headings, seen from the true camera; a scene a stage refused
    has no Detections, so the tracker skips it as the service would. Confirmed and lost (coasting)
    tracks of the target are the scene's hypotheses; a target in the scene but below the visibility
    rule is "hidden".
    """
    tracker = Tracker(config)
    truth, hidden, tracks = [], [], []
    for record in records:
        # the detections are placed relative to the true camera, so that is where they were seen from
        camera = record.T_world_cam_true
        viewpoint_m = None if camera is None else np.asarray(camera, np.float64)[:3, 3]
        if record.error is None:
            tracker.update(
                [
                    TrackInput(
                        d["target"],
                        record.sensor_relative(d["position_m"]),
                        record.sensor_relative_yaw(d["yaw_rad"]) if "yaw_rad" in d else None,
                        d["score"],
                        viewpoint_m,
                    )
                    for d in record.detections
                ],
                record.stamp_ns,
            )
        instances = [t for t in record.truth if t["name"] == target]
        truth.append(
            [np.asarray(t["position_m"]) for t in instances if t["visible_fraction"] >= present]
        )
        hidden.append(
            [np.asarray(t["position_m"]) for t in instances if t["visible_fraction"] < present]
        )
        established = [t for t in tracker.tracks if t.target == target and t.state != "tentative"]
        tracks.append(
            [
                (t.id, t.position_m.copy())
                for t in sorted(established, key=lambda t: (-t.hits, t.id))
            ]
        )
    return score_tracks(truth, tracks, hidden_positions_m=hidden)


def _template_scales(arm: Any, plan_: Plan) -> dict[str, list[float]]:
    """A 2D arm's template sizes when it keeps several (the scaled-templates variant, labelled apart)."""
    scales = list(plan_.b2d.template_scales)
    return {"template_scales": scales} if arm.is_2d and len(scales) > 1 else {}


_OUTPUT_OPTIONS = ("--results", "--json")
"""Options that say where results are written: they decide nothing in them."""


def _without_outputs(argv: Sequence[str]) -> list[str]:
    """The command line without the options that name where results go (`_OUTPUT_OPTIONS`), so that a
    result committed elsewhere names no folder of the machine it ran on.
    """
    out: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg in _OUTPUT_OPTIONS:
            skip = True
        elif not arg.startswith(tuple(f"{o}=" for o in _OUTPUT_OPTIONS)):
            out.append(arg)
    return out


def rows(plan_: Plan, results: dict[tuple[Any, Any], list[Any]]) -> tuple[list[dict], list[dict]]:
    """The contract rows (results.json) and the detailed rows (details.json) of every run."""
    contract, details = [], []
    worlds: dict[Any, tuple[list[str], Any, Any]] = {}
    for flight in plan_.flights:
        world_key = replace(flight, noise="none")  # noise settings share their flight's world
        for arm in plan_.arms:
            records = results[(flight, arm)]
            s = summarise(records, flight.target, plan_.config.sim.present_min_visible_fraction)
            ts = track_score(
                records,
                flight.target,
                plan_.config.sim.present_min_visible_fraction,
                plan_.config.tracking,
            )
            fp_on: dict[str, int] = {}
            if s.counts.fp:
                if world_key not in worlds:
                    worlds[world_key] = flight_vehicles(flight, plan_.config.sim)
                fp_on = false_positives_on(records, s.outcomes, flight.target, worlds[world_key])
            row = {
                "scenario": flight.scenario,
                "run": flight.run,
                "pipeline": arm.pipeline,
                "descriptor": arm.descriptor,
                "noise": flight.noise,
                "tp": s.counts.tp,
                "fp": s.counts.fp,
                "fn": s.counts.fn,
                "f1": s.counts.f1,
                "t_error_median_m": s.t_error_median_m,
                "time_per_scene_ms": s.time_per_scene_ms,
                "scenes": s.scenes,
                "track_tp": ts.counts.tp,
                "track_fp": ts.counts.fp,
                "track_fn": ts.counts.fn,
                "track_f1": ts.counts.f1,
                "false_tracks": ts.false_tracks,
                "scenes_to_confirm": ts.scenes_to_confirm,
                "track_held_while_hidden": ts.held_while_hidden,
                "track_t_error_median_m": ts.t_error_median_m,
            }
            sc = preset(flight.scenario, flight.run)
            storage = plan_.storage_kb.get(storage_key(arm, flight))
            contract.append(jsonable(row))
            details.append(
                jsonable(
                    row
                    | {
                        "seed": flight.seed,
                        "frames": flight.frames,
                        "every": flight.every,
                        "target": flight.target,
                        "tn": s.counts.tn,
                        "range_m": sc.range_m,
                        "obliquity_deg": sc.obliquity_deg,
                        "scenes_with_target": s.scenes_with_target,
                        "errors": s.errors,
                        "t_errors_m": list(s.t_errors_m),
                        "outcomes": list(s.outcomes),
                        "nav_error_median_m": s.nav_error_median_m,
                        "stages_ms": s.stages_ms,
                        "cloud_points_median": float(np.median([r.cloud_points for r in records]))
                        if records
                        else None,
                        "template_storage_kb": storage,
                        "reference_ms": plan_.reference_ms.get(flight),
                        "false_positives_on": fp_on,
                    }
                    | _template_scales(arm, plan_)
                )
            )
    return contract, details


def write_outputs(
    plan_: Plan,
    contract: list[dict],
    details: list[dict],
    json_path: Path | None,
    argv: Sequence[str],
) -> Path:
    """Write results/<timestamp>/ (results, details, config), point `latest` at it."""
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    out = plan_.results / stamp
    n = 1
    while out.exists():
        out = plan_.results / f"{stamp}-{n}"
        n += 1
    out.mkdir(parents=True)
    (out / "results.json").write_text(json.dumps({"results": contract}, indent=1))
    (out / "details.json").write_text(json.dumps({"results": details}, indent=1))
    (out / "config.json").write_text(
        json.dumps(
            jsonable(
                {
                    "command": ["atr", "eval", *_without_outputs(argv)],
                    "code_version": plan_.version,
                    "overrides": plan_.overrides,
                    "atr": to_dict(plan_.config),
                    "baseline2d": plan_.b2d,
                    "flights": plan_.flights,
                    "arms": plan_.arms,
                }
            ),
            indent=1,
        )
    )
    latest = plan_.results / "latest"
    tmp = plan_.results / f".latest.{os.getpid()}"
    tmp.symlink_to(out.name)
    tmp.replace(latest)
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({"results": contract}, indent=1))
    return out
