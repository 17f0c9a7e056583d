"""Time per scene of the paper's sparse arm (GFTT/KLT SfM + the matcher), per descriptor and per stage.

The evaluation's own computation (`atr.evaluation.runner.run_flight`, one process: `atr eval --jobs 1`) on a
sample of scenario 1 and 2 scenes, its frames simulated once and processed ``--repeats`` times. Per
descriptor it prints the median time per scene (pooled over the scenes, median over the repeats), that time
as a ratio to the evaluation's reference workload timed in the same process just before, the paper's
Table V figure, and each stage's median time and share. With ``--digest`` it prints a hash of every
scene's detections and error per descriptor, to show a change leaves the results as they were.

    python bench/sparse_arm.py [--scenario 1 2] [--run 3] [--every 5] [--frames N] [--repeats 3]
                               [--descriptors shot usc ...] [--digest]

Set OPENBLAS_NUM_THREADS=1 on a shared machine (./dev does): BLAS threads fighting for busy cores
inflate the times.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import statistics
from collections import defaultdict

from atr.evaluation.aggregate import PAPER_TABLE_V_TIME_S
from atr.evaluation.experiment import Request, _templates_3d, plan
from atr.evaluation.runner import SceneRecord, flight_frames, run_flight
from atr.evaluation.timing import REFERENCE_WORKLOAD, reference_workload_ms
from atr.recognition import STAGES

PAPER_S: dict[str, float] = PAPER_TABLE_V_TIME_S["gftt-sfm"]
"""The paper's processing time per scene of the SfM GFTT arm (Table V), seconds."""

SFM_STAGES: tuple[str, ...] = ("sfm_correspondences", "sfm_triangulation")


def _digest(records: list[SceneRecord]) -> str:
    """Hash of what a run decided: each scene's frame, detections and error (not its times)."""
    data = [(r.frame, r.detections, r.error, r.cloud_points) for r in records]
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--run", type=int, nargs="+", default=[3])
    ap.add_argument("--every", type=int, default=5)
    ap.add_argument("--frames", type=int, default=None, help="only the first N frames of each run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--descriptors", nargs="+", default=list(PAPER_S))
    ap.add_argument("--digest", action="store_true", help="print a hash of the detections")
    args = ap.parse_args()

    request = Request(
        scenarios=tuple(args.scenario),
        runs=tuple(args.run),
        frames=args.frames,
        every=args.every,
        pipelines=("gftt-sfm",),
        descriptors=tuple(args.descriptors),
        overrides=("sim.nav_fix_every_frame=true",),
    )
    p = plan(request)
    _templates_3d(p)
    frames = {f: list(flight_frames(f, p.config, lidar=False)) for f in p.flights}
    run_flight(p.flights[0], p.arms, p.config, p.templates_3d, frames=frames[p.flights[0]])  # JIT

    per_scene: dict[str, list[float]] = defaultdict(list)  # descriptor -> each repeat's median
    stages: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    refs, digests = [], {}
    for _ in range(args.repeats):
        refs.append(reference_workload_ms())
        pooled: dict[str, list[SceneRecord]] = defaultdict(list)
        for flight in p.flights:
            out = run_flight(flight, p.arms, p.config, p.templates_3d, frames=frames[flight])
            for arm, records in out.items():
                pooled[arm.descriptor] += records
        for desc, records in pooled.items():
            per_scene[desc].append(statistics.median(r.time_ms for r in records))
            for name in (*SFM_STAGES, *STAGES):
                stages[desc][name].append(
                    statistics.median(r.stages_ms.get(name, 0.0) for r in records)
                )
            digests[desc] = _digest(records)

    ref = statistics.median(refs)
    scenes = len(pooled[args.descriptors[0]])
    flights = ", ".join(f"scenario {f.scenario} run {f.run}" for f in p.flights)
    print(f"{scenes} scenes ({flights}, every {args.every}), {args.repeats} repeats, one process")
    print(f"reference ({REFERENCE_WORKLOAD}): {ref:.1f} ms (each repeat: {refs_text(refs)})")
    names = (*SFM_STAGES, *STAGES)
    short = ["corr", "triang", *STAGES]
    print(
        f"{'descriptor':10} {'ms/scene':>8} {'x ref':>6} {'paper s':>7} "
        + " ".join(f"{s:>9}" for s in short)
        + ("  digest" if args.digest else "")
    )
    for desc in args.descriptors:
        t = statistics.median(per_scene[desc])
        med = {n: statistics.median(stages[desc][n]) for n in names}
        print(
            f"{desc:10} {t:8.0f} {t / ref:6.2f} {PAPER_S.get(desc, float('nan')):7.2f} "
            + " ".join(f"{med[n]:9.1f}" for n in names)
            + (f"  {digests[desc]}" if args.digest else "")
        )
    print("stage shares of the summed stage medians (%):")
    for desc in args.descriptors:
        med = {n: statistics.median(stages[desc][n]) for n in names}
        total = sum(med.values()) or 1.0
        print(f"{desc:10} " + " ".join(f"{100 * med[n] / total:9.1f}" for n in names))


def refs_text(refs: list[float]) -> str:
    """The reference times as a short list."""
    return ", ".join(f"{r:.1f}" for r in refs)


if __name__ == "__main__":
    main()
