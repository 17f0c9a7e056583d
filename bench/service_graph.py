"""Service graph benchmark: scenes per second and frame-to-detection latency with frames at the camera's pace.

`atr run` replays in lock-step: the next frame waits for the last answer, so it measures the sum of the
services' times. In flight the camera does not wait. Here the frames go out at the recorded pace times each
`--rate` (`atr run --rate`), the processes run side by side as they do in flight (SfM of one scene while the
matcher works on the previous one), and the output recording gives, per scene:

- latency: the Detections message's log time minus its frame's (both stamped by the recorder, one clock),
  over every scene and in the steady state: from the first scene, after a track is confirmed, that left
  within a frame interval (before it, the scenes wait behind the flight's first whole searches);
- the interval between scenes, sustained: the span of the Detections over the scenes answered after the first;
- frames unanswered (a service that falls behind drops inputs once its queue is full, and says so);
- the scenes that waited for a whole search still running in the matcher's worker when its joining
  frame came (their Timing's "join_wait"): the lag (`tracking.whole_search_lag_frames`) is too short
  for this machine at this rate.

Beside it, the services' own time per scene (their Timing messages), the CPU time each process (every
service, the matcher's worker, this process replaying the recording) spent per frame between the
flight's first frame and its last answer (sampled twice a second with psutil, which comes with Dask's
distributed: on two cores the frames keep coming only while these add up to less than two frame
intervals), and the reference workload of `atr.evaluation.timing` timed in this process, so the
figures compare across machines.

Run: ./dev bench service_graph [--input FLIGHT.mcap] [--frames 21] [--rates 1 2.5] [--keep DIR]
Without --input, scenario 1 run 3 (50 m, 30 degrees) is simulated once into a temporary folder.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import psutil

from atr.evaluation.timing import REFERENCE_WORKLOAD, reference_workload_ms
from bus import codec
from bus.mcap_tools import iter_messages
from bus.pipeline import run_recording


def simulate(folder: Path, frames: int) -> Path:
    """A flight recording: scenario 1 run 3, the default camera."""
    path = folder / "flight.mcap"
    command = [sys.executable, "-m", "cli.main", "simulate", "--scenario", "1", "--run", "3"]
    command += ["--frames", str(frames)]
    subprocess.run([*command, "--out", str(path)], check=True, stdout=subprocess.DEVNULL)
    return path


def measure(out: Path, uav: str = "uav1") -> dict[str, float]:
    """Latency and interval of the scenes answered in a paced run's recording, seconds."""
    frame_s: dict[int, float] = {}
    answer_s: dict[int, float] = {}
    busy_ms: dict[str, list[float]] = {}
    join_wait_ms: list[float] = []
    held_from: int | None = None  # the stamp of the first scene with a confirmed track
    for topic, message in iter_messages(out):
        if topic == f"atr/{uav}/camera/image":
            frame_s[message.publish_time] = message.log_time / 1e9
        elif topic == f"atr/{uav}/detections":
            answer_s[message.publish_time] = message.log_time / 1e9
        elif topic == f"atr/{uav}/tracks" and held_from is None:
            tracks = codec.unpack(message.data)["tracks"]
            if any(t["state"] == "confirmed" for t in tracks):
                held_from = message.publish_time
        elif topic.startswith(f"atr/{uav}/") and topic.endswith("/timing"):
            timing = codec.unpack(message.data)
            busy_ms.setdefault(timing["service"], []).append(float(timing["total_ms"]))
            if "join_wait" in timing["stages_ms"]:
                join_wait_ms.append(float(timing["stages_ms"]["join_wait"]))
    answered = sorted(s for s in answer_s if s in frame_s)
    latency_s = [answer_s[s] - frame_s[s] for s in answered]
    # the steady state: from the first scene, after a track is confirmed, that left within a frame
    # interval of its frame (the queue the flight's first whole searches built has drained)
    interval_s = float(np.median(np.diff(sorted(frame_s.values())))) if len(frame_s) > 1 else 0.0
    steady = [
        k
        for k, s in enumerate(answered)
        if held_from is not None and s > held_from and latency_s[k] < interval_s
    ]
    steady_s = latency_s[steady[0] :] if steady else []
    answers_s = sorted(answer_s[s] for s in answered)
    figures = {
        "frames": float(len(frame_s)),
        "scenes": float(len(answered)),
        "frame_interval_s": interval_s,
        # sustained: the answers' span over the scenes answered after the first
        "scene_interval_s": (answers_s[-1] - answers_s[0]) / (len(answers_s) - 1)
        if len(answers_s) > 1
        else float("nan"),
        "latency_p50_s": float(np.percentile(latency_s, 50)) if latency_s else float("nan"),
        "latency_p95_s": float(np.percentile(latency_s, 95)) if latency_s else float("nan"),
        "scenes_before_steady": float(len(answered) - len(steady_s)),
        "steady_latency_p95_s": float(np.percentile(steady_s, 95)) if steady_s else float("nan"),
        "latency_max_s": float(max(latency_s)) if latency_s else float("nan"),
        "first_frame_s": min(frame_s.values()) if frame_s else float("nan"),
        "last_answer_s": answers_s[-1] if answers_s else float("nan"),
        "scenes_waited": float(len(join_wait_ms)),
        "join_wait_max_s": max(join_wait_ms) / 1e3 if join_wait_ms else 0.0,
    }
    for service, ms in sorted(busy_ms.items()):
        figures[f"{service}_ms"] = statistics.median(ms)
    return figures


class CpuSampler:
    """CPU seconds (user + system) of this process and every process it started, by name, sampled
    twice a second on a thread while a paced run goes on."""

    def __init__(self, period_s: float = 0.5) -> None:
        self.samples: list[tuple[float, dict[int, tuple[str, float]]]] = []
        self._period_s = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cpu-sampler", daemon=True)

    def __enter__(self) -> CpuSampler:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            sample = {}
            for process in [me, *me.children(recursive=True)]:
                try:
                    times = process.cpu_times()
                    sample[process.pid] = (_name(process, me), times.user + times.system)
                except psutil.Error:  # it ended between the listing and the reading
                    continue
            self.samples.append((time.time(), sample))
            self._stop.wait(self._period_s)

    def per_frame_ms(self, start_s: float, end_s: float, frames: float) -> dict[str, float]:
        """Each process's CPU milliseconds per frame between the samples nearest inside the span."""
        inside = [(t, sample) for t, sample in self.samples if start_s <= t <= end_s]
        if len(inside) < 2 or frames <= 0:
            return {}
        (t0, first), (t1, last) = inside[0], inside[-1]
        frames_inside = frames * (t1 - t0) / max(end_s - start_s, 1e-9)
        spent: dict[str, float] = {}
        for pid, (name, cpu_s) in last.items():
            before = first[pid][1] if pid in first else 0.0
            spent[name] = spent.get(name, 0.0) + (cpu_s - before) * 1e3 / frames_inside
        return dict(sorted(spent.items(), key=lambda kv: -kv[1]))


def _name(process: psutil.Process, me: psutil.Process) -> str:
    """A process by what it is: a service by name, the matcher's worker, this replayer."""
    if process.pid == me.pid:
        return "replayer"
    command = process.cmdline()
    if "service" in command and command.index("service") + 1 < len(command):
        return command[command.index("service") + 1]
    if any("spawn_main" in part for part in command):
        return "worker"  # the whole-search lane's process (the matcher's child)
    return process.name()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--input", type=Path, help="a flight recording (default: simulate one)")
    parser.add_argument("--frames", type=int, default=21, help="frames of the simulated flight")
    parser.add_argument("--rates", type=float, nargs="+", default=[1.0, 2.5])
    parser.add_argument("--layout", default="local")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument(
        "--keep",
        type=Path,
        help="write the paced runs' recordings here (default: a temporary folder)",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.keep:
            args.keep.mkdir(parents=True, exist_ok=True)
        flight = args.input or simulate(folder, args.frames)
        reference_ms = reference_workload_ms()
        print(f"reference workload ({REFERENCE_WORKLOAD}): {reference_ms:.1f} ms")
        for rate in args.rates:
            out = (args.keep or folder) / f"paced-{rate:g}.mcap"
            with CpuSampler() as cpu:
                result = run_recording(
                    flight, out, layout=args.layout, overrides=args.overrides, rate=rate
                )
            if result.failures:
                sys.exit(f"processes failed: {sorted(result.failures)} (logs: {result.log_dir})")
            f = measure(out)
            busy = "  ".join(f"{k[:-3]} {v:.0f} ms" for k, v in f.items() if k.endswith("_ms"))
            spent = cpu.per_frame_ms(f["first_frame_s"], f["last_answer_s"], f["frames"])
            spent_text = "  ".join(f"{k} {v:.0f} ms" for k, v in spent.items() if v >= 0.5)
            print(
                f"rate {rate:g}: a frame every {f['frame_interval_s'] * 1e3:.0f} ms; "
                f"{f['scenes']:.0f} of {f['frames']:.0f} frames answered "
                f"({result.timeouts} unanswered); a scene every "
                f"{f['scene_interval_s'] * 1e3:.0f} ms ("
                f"{f['scene_interval_s'] * 1e3 / reference_ms:.1f} x reference); latency p50 "
                f"{f['latency_p50_s'] * 1e3:.0f} ms, p95 {f['latency_p95_s'] * 1e3:.0f} ms, max "
                f"{f['latency_max_s'] * 1e3:.0f} ms; steady (after the first "
                f"{f['scenes_before_steady']:.0f} scenes) p95 {f['steady_latency_p95_s'] * 1e3:.0f} ms; "
                f"{f['scenes_waited']:.0f} scenes waited for a whole search (at most "
                f"{f['join_wait_max_s'] * 1e3:.0f} ms)\n"
                f"    each service's own time per input (median): {busy}\n"
                f"    CPU per frame, first frame to last answer: {spent_text} "
                f"(together {sum(spent.values()):.0f} ms)"
            )


if __name__ == "__main__":
    main()
