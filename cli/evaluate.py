r"""Run the paper's experiments (§III) and score them with its F1 (§III-C): `atr eval`.

Any selection of scenarios x runs x pipelines x descriptors x noise settings, each flight simulated once and
processed by every selected pipeline. In-process by default (the services' functions, same seeds: identical
detections), or through the real service graph with --via-services (`atr simulate` then `atr run` per
pipeline; the 2D baseline has no service and always runs in-process). In-process flights run here one at a
time (--jobs 1), or as tasks on Dask distributed: a LocalCluster of N worker processes (--jobs N) or the
cluster at --scheduler ADDRESS; on a terminal a bar per pipeline/descriptor shows its scenes and ETA.
Results are cached per (flight, pipeline, descriptor) keyed by every parameter and the code version, so an
interrupted evaluation resumes.
Each invocation writes results/<timestamp>/ (results.json: the contract; details.json: per-run details for
`atr report`; config.json: the effective configuration) and points results/latest at it.

Pipelines: gftt-sfm, surf-sfm (the paper's SfM 3D ATR), sgm-sfm (ours: dense semi-global matching of the
pair rectified with the known pose), lidar (3D LIDAR ATR), 2d-1 .. 2d-4 (Table IV pairs).

Examples:
    atr eval --scenario 1 --run 3 --frames 5 --pipeline gftt-sfm --pipeline lidar --descriptor shot
    atr eval --pipeline gftt-sfm --pipeline lidar --pipeline 2d-1 --descriptor shot --descriptor fpfh \\
        --noise none --noise shot --noise gaussian:10 --noise gaussian:30 --jobs 2     # the full evaluation
    atr eval --scenario 1 --run 3 --frames 4 --via-services --set sim.width_px=640 --set sim.height_px=480
    atr eval --pipeline gftt-sfm --descriptor shot --scheduler tcp://10.0.0.5:8786   # on a Dask cluster

"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the evaluation loads the simulator and the matchers: only when a command runs
    from collections.abc import Mapping

    from atr.evaluation.experiment import Plan
    from atr.evaluation.runner import Arm, Flight, SceneRecord

REPO = Path(__file__).resolve().parents[1]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr eval`."""
    from cli._args import add_repeatable
    from cli.world import add_vehicle_arguments

    add_repeatable(parser, "--scenario", "Table II scenario", "all", type=int)
    add_repeatable(parser, "--run", "run within each scenario", "all", type=int)
    parser.add_argument(
        "--frames", type=int, help="only the first N frames of each run (N - 1 scenes)"
    )
    parser.add_argument(
        "--every",
        type=int,
        default=1,
        help="only every K-th scene of each run: a sample of the whole run (default 1: all; with "
        "track-guided search, sgm-sfm's default, the tracks see only the sampled scenes)",
    )
    add_repeatable(
        parser, "--pipeline", "gftt-sfm, surf-sfm, sgm-sfm, lidar, 2d-1..2d-4", "gftt-sfm"
    )
    add_repeatable(parser, "--descriptor", "3D descriptor of the 3D pipelines", "the config's")
    add_repeatable(
        parser, "--noise", "none, shot, gaussian:10, gaussian:30, nav (GNSS/INS errors on the fix)"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="world seed (0 is reported; others tune)"
    )
    parser.add_argument(
        "--target-mesh",
        help="mesh file of the target (its template and its world): FILE[:units=mm,up=y]",
    )
    add_repeatable(parser, "--clutter-mesh", "extra confuser mesh")
    add_vehicle_arguments(parser)  # --target NAME, --clutter NAME: vehicles of the family
    parser.add_argument(
        "--targets",
        metavar="NAMES",
        help="held-out targets: 'all' or a comma list of vehicles of the family, each the target "
        "in turn with the rest of the family as confusers (docs/evaluation/protocol.md)",
    )
    parser.add_argument(
        "--json", type=Path, help="also write the results table here (the contract)"
    )
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="GROUP.FIELD=VALUE"
    )
    where = parser.add_mutually_exclusive_group()  # where the flights run
    where.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="flights at once: 1 runs them here, N > 1 on a Dask LocalCluster of N worker processes",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask scheduler whose workers run the flights (tcp://HOST:8786), instead of --jobs",
    )
    parser.add_argument("--results", type=Path, default=REPO / "results", help="results folder")
    parser.add_argument(
        "--via-services",
        action="store_true",
        help="run the 3D pipelines through the real service graph from recordings",
    )
    parser.add_argument(
        "--force", action="store_true", help="recompute runs even when a current result exists"
    )


class _Bars:
    """A bar per arm with its ETA (tqdm), on stderr when it is a terminal, and the lines of progress
    above them; in a log (not a terminal) only the lines, one per finished flight.
    """

    def __init__(self) -> None:
        self._bars: dict[Arm, Any] = {}

    def start(self, scenes: Mapping[Arm, int]) -> None:
        from tqdm import tqdm

        names = {arm: f"{arm.pipeline}/{arm.descriptor}" for arm in scenes}
        width = max(map(len, names.values()), default=0)
        for position, (arm, total) in enumerate(scenes.items()):
            self._bars[arm] = tqdm(
                total=total,
                desc=names[arm].ljust(width),
                unit="scene",
                position=position,
                file=sys.stderr,
                disable=None,  # off when stderr is not a terminal
                dynamic_ncols=True,
            )

    def advance(self, arm: Arm, scenes: int) -> None:
        if scenes:
            self._bars[arm].update(scenes)

    def note(self, text: str) -> None:
        from tqdm import tqdm

        tqdm.write(text, file=sys.stderr)  # above the bars
        sys.stderr.flush()

    def close(self) -> None:
        for bar in self._bars.values():
            bar.close()


def plan(args: argparse.Namespace) -> Plan:
    """The evaluation plan of `atr eval`'s arguments."""
    from atr.evaluation.experiment import Request, plan
    from atr.io.mesh import vehicle_sources

    target, clutter = vehicle_sources(
        getattr(args, "target", None),
        args.target_mesh,
        getattr(args, "clutter", ()),
        args.clutter_mesh,
    )
    return plan(
        Request(
            scenarios=tuple(args.scenario or ()),
            runs=tuple(args.run or ()),
            frames=args.frames,
            every=args.every,
            pipelines=tuple(args.pipeline or ["gftt-sfm"]),
            descriptors=tuple(args.descriptor or ()),
            noises=tuple(args.noise or ["none"]),
            seed=args.seed,
            target_mesh=target,
            clutter_meshes=clutter,
            targets=_targets(getattr(args, "targets", None)),
            overrides=tuple(args.overrides),
            results=args.results,
            via_services=bool(getattr(args, "via_services", False)),
        )
    )


def execute(
    plan_: Plan, *, via_services: bool = False, **where: Any
) -> dict[tuple[Flight, Arm], list[SceneRecord]]:
    """Every (flight, arm) result of a plan, computed or loaded, with progress on stderr.

    Args:
        plan_: what to evaluate.
        via_services: run the 3D pipelines through the real service graph from recordings.
        where: ``jobs``, ``scheduler`` and ``force``, as `atr.evaluation.experiment.execute` takes them.

    """
    from atr.evaluation.experiment import execute

    runner = None
    if via_services:
        from bus.evaluation import run_via_services as runner  # the bus loads only for this

    bars = _Bars()
    try:
        return execute(plan_, via_services=runner, progress=bars.note, bars=bars, **where)
    finally:
        bars.close()


def _targets(text: str | None) -> tuple[str, ...]:
    """The vehicles `--targets` names: every one of the family for "all"."""
    from atr.sim.vehicles import VEHICLES

    if not text:
        return ()
    return (
        tuple(VEHICLES) if text == "all" else tuple(t.strip() for t in text.split(",") if t.strip())
    )


def run(args: argparse.Namespace) -> int:
    """Plan, compute what is missing, score, write."""
    from atr.evaluation.tables import rows, write_outputs
    from atr.scaleout import SchedulerError
    from cli._args import forwarded

    plan_ = plan(args)
    try:
        results = execute(plan_, **forwarded(args, "jobs", "scheduler", "via_services", "force"))
    except SchedulerError as exc:
        print(f"atr eval: {exc}", file=sys.stderr)
        return 2
    contract, details = rows(plan_, results)
    out = write_outputs(
        plan_, contract, details, args.json, sys.argv[2:] if len(sys.argv) > 2 else []
    )
    header = (
        f"{'scen':>4} {'run':>3} {'pipeline':<9} {'descriptor':<11} {'noise':<11} "
        f"{'TP':>4} {'FP':>4} {'FN':>4} {'F1':>6} {'Terr m':>7} {'ms/scene':>9}"
    )
    print(header)
    for r in contract:
        f1 = "-" if r["f1"] is None else f"{r['f1']:.3f}"
        te = "-" if r["t_error_median_m"] is None else f"{r['t_error_median_m']:.2f}"
        ms = "-" if r["time_per_scene_ms"] is None else f"{r['time_per_scene_ms']:.0f}"
        print(
            f"{r['scenario']:>4} {r['run']:>3} {r['pipeline']:<9} {r['descriptor']:<11} "
            f"{r['noise']:<11} {r['tp']:>4} {r['fp']:>4} {r['fn']:>4} {f1:>6} {te:>7} {ms:>9}"
        )
    if len({flight.target for flight in plan_.flights}) > 1:
        _print_targets(details, out)
    print(f"results in {out}")
    return 0


def _print_targets(details: list[dict], out: Path) -> None:
    """F1 per target x range x obliquity and pooled over the held-out targets, per arm; also written
    to <out>/targets.json.
    """
    import json

    from atr.evaluation.aggregate import arm_label, target_table
    from atr.evaluation.io import jsonable

    tables = {}
    for arm in dict.fromkeys(arm_label(r) for r in details):
        rows = [r for r in details if arm_label(r) == arm and r["noise"] == "none"]
        tables[arm] = table = target_table(rows)
        print(f"{arm}: F1 per target (range m / obliquity deg), * = held out")
        for t in table["targets"]:
            cells = " ".join(
                f"{c['range_m']:.0f}/{c['obliquity_deg']:.0f} {c['f1']:.2f}"
                for c in table["cells"]
                if c["target"] == t["target"]
            )
            mark = "*" if t["held_out"] else " "
            print(f"  {t['target']:<9}{mark} {t['f1']:.3f}  {cells}")
        for h in table["held_out"]:
            where = "all" if h["obliquity_deg"] is None else f"{h['obliquity_deg']:.0f} deg"
            print(
                f"  held out, {where}: F1 {h['f1']:.3f} ({h['tp']}/{h['fp']}/{h['fn']}), "
                f"FPs on other vehicles {h['fp_on_vehicles']} of {h['scenes']} scenes"
            )
    (out / "targets.json").write_text(json.dumps(jsonable(tables), indent=1))
