"""`atr recognize` on PCL's milk scene as a user runs it: the whole process, start-up included, one thread.

The goal (issue 32) is PCL's own C++ correspondence-grouping process on the same files, one thread (~2.4 s
on this machine). Each run is a fresh `python -m cli.main recognize ... --json` with one OpenMP/numba thread;
one warm-up run first fills numba's cache, as any second run of the command finds it. Prints the median over
the runs of: the process's wall time, its CPU time (user + system: what one idle core would take), the
matcher's own stages (`stage_times_ms.total` of its JSON) and the rest (imports, file reading, template,
exit), and the wall time as a ratio to a fixed numpy reference workload timed in this process (so figures
compare across machines), with the machine's load.

    python bench/startup.py [--runs 7] [--descriptor shot] [--data ../shared/data/pcl]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from atr.evaluation.timing import REFERENCE_WORKLOAD, reference_workload_ms

REPO = Path(__file__).resolve().parents[1]
PCL_DATA = REPO.parent / "shared" / "data" / "pcl"
MODEL, SCENE = "milk.pcd", "milk_cartoon_all_small_clorox.pcd"


def one_run(command: list[str], env: dict[str, str]) -> dict[str, float]:
    """One whole `atr recognize` process: wall and CPU seconds, and its matcher's stage total."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, check=False)
    wall_s = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{done.stderr}")
    out = json.loads(done.stdout)
    return {
        "wall_s": wall_s,
        "cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
        "matcher_s": out["stage_times_ms"]["total"] / 1e3,
        "detections": len(out["detections"]),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--descriptor", default="shot")
    ap.add_argument("--data", type=Path, default=PCL_DATA, help="folder holding PCL's milk files")
    args = ap.parse_args()
    if not (args.data / SCENE).is_file():
        print(f"{args.data / SCENE} not found: pass --data (PCL's test data)", file=sys.stderr)
        return 2
    command = [
        sys.executable,
        "-m",
        "cli.main",
        "recognize",
        "--model",
        str(args.data / MODEL),
        "--scene",
        str(args.data / SCENE),
        "--descriptor",
        args.descriptor,
        "--resolution",
        "auto",
        "--viewpoint",
        "0",
        "0",
        "0",
        "--json",
    ]
    env = os.environ | {"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    one_run(command, env)  # warm-up: numba's cache
    runs = [one_run(command, env) for _ in range(args.runs)]
    ref_ms = reference_workload_ms()
    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    print(
        f"atr recognize, {args.descriptor}, milk in {SCENE}, one thread, median of {args.runs} "
        f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)"
    )
    print(f"reference ({REFERENCE_WORKLOAD}): {ref_ms:.1f} ms")
    print(
        f"whole process: wall {med['wall_s']:.2f} s (x ref {1e3 * med['wall_s'] / ref_ms:.1f}), "
        f"CPU {med['cpu_s']:.2f} s (min {min(r['cpu_s'] for r in runs):.2f}); matcher stages "
        f"{med['matcher_s']:.2f} s, the rest {med['wall_s'] - med['matcher_s']:.2f} s; "
        f"{med['detections']:.0f} detections"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
