"""A fixed workload timed beside the evaluation, so that its time figures compare across runs.

The same code on the same machine can take tens of per cent more or less time within an hour when the
machine is shared (docs/evaluation/discussion.md): a per-scene time alone cannot tell a slower change from a
slower hour. Timing a workload that never changes in the same process, just before the work, gives the
ratio that can. Across machines the ratio is a rough guide only, and the workload is a scalar one for that
reason: numpy's default sort of float64 takes a vector path where the CPU offers AVX-512 (x86-simd-sort),
ten times faster than without it (4.7 against 53 ms), which would make one machine's ratios incomparable with
another's; its stable sort (a timsort) has no vector path.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

REFERENCE_WORKLOAD = "numpy stable sort of 1,000,000 float64, median of 5"
"""What ``reference_workload_ms`` times (as the reports name it)."""


def reference_workload_ms(repeats: int = 5) -> float:
    """Median wall time of stable-sorting the same 1,000,000 random float64 values, milliseconds."""
    values = np.random.default_rng(0).random(1_000_000)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        np.sort(values, kind="stable")
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)
