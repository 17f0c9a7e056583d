r"""Run the paper's experiments (§III) and score them with its F1 (§III-C): `atr eval`.

Any selection of scenarios x runs x pipelines x descriptors x noise settings, each flight simulated once and
processed by every selected pipeline. In-process by default (the services' functions, same seeds: identical
detections), or through the real service graph with --via-services (`atr simulate` then `atr run` per
pipeline; the 2D baseline has no service and always runs in-process). Results are cached per (flight,
pipeline, descriptor) keyed by every parameter and the code version, so an interrupted evaluation resumes.
Each invocation writes results/<timestamp>/ (results.json: the contract; details.json: per-run details for
`atr report`; config.json: the effective configuration) and points results/latest at it.

Pipelines: gftt-sfm, surf-sfm (the paper's SfM 3D ATR), sgm-sfm (ours: dense semi-global matching of the
pair rectified with the known pose), lidar (3D LIDAR ATR), 2d-1 .. 2d-4 (Table IV pairs).

Examples:
    atr eval --scenario 1 --run 3 --frames 5 --pipeline gftt-sfm --pipeline lidar --descriptor shot
    atr eval --pipeline gftt-sfm --pipeline lidar --pipeline 2d-1 --descriptor shot --descriptor fpfh \\
        --noise none --noise shot --noise gaussian:10 --noise gaussian:30 --jobs 2     # the full evaluation
    atr eval --scenario 1 --run 3 --frames 4 --via-services --set sim.width_px=640 --set sim.height_px=480

"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
NOISES = ("none", "shot", "gaussian:10", "gaussian:30")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr eval`."""
    parser.add_argument(
        "--scenario", type=int, action="append", help="Table II scenario (repeatable; default all)"
    )
    parser.add_argument(
        "--run",
        type=int,
        action="append",
        help="run within each scenario (repeatable; default all)",
    )
    parser.add_argument(
        "--frames", type=int, help="only the first N frames of each run (N - 1 scenes)"
    )
    parser.add_argument(
        "--every",
        type=int,
        default=1,
        help="only every K-th scene of each run: a sample of the whole run (default 1: all)",
    )
    parser.add_argument(
        "--pipeline",
        action="append",
        help="gftt-sfm, surf-sfm, sgm-sfm, lidar, 2d-1..2d-4 (repeatable; default gftt-sfm)",
    )
    parser.add_argument(
        "--descriptor",
        action="append",
        help="3D descriptor of the 3D pipelines (repeatable; default the config's)",
    )
    parser.add_argument(
        "--noise", action="append", help="none, shot, gaussian:10, gaussian:30 (repeatable)"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="world seed (0 is reported; others tune)"
    )
    parser.add_argument(
        "--target-mesh", help="mesh file of the target (its template and its world)"
    )
    parser.add_argument(
        "--clutter-mesh", action="append", default=[], help="extra confuser mesh (repeatable)"
    )
    parser.add_argument(
        "--json", type=Path, help="also write the results table here (the contract)"
    )
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="GROUP.FIELD=VALUE"
    )
    parser.add_argument(
        "--jobs", type=int, default=1, help="worker processes (flights run in parallel)"
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


@dataclass
class Plan:
    """What an invocation evaluates."""

    config: Any  # AtrConfig
    overrides: list[str]
    flights: list[Any]  # Flight
    arms: list[Any]  # Arm
    version: str
    results: Path
    b2d: Any  # Baseline2dConfig
    templates_3d: dict[str, list[Any]] = field(default_factory=dict)
    templates_2d: dict[str, list[Any]] = field(default_factory=dict)
    storage_kb: dict[tuple[str, str], float] = field(default_factory=dict)
    reference_ms: dict[Any, float] = field(default_factory=dict)  # Flight -> the workload's time


def _flights(args: argparse.Namespace) -> list[Any]:
    from atr.errors import ConfigError  # noqa: PLC0415
    from atr.evaluation.runner import Flight  # noqa: PLC0415
    from atr.sim.noise import parse_noise  # noqa: PLC0415
    from atr.sim.scenarios import TABLE_II  # noqa: PLC0415

    scenarios = args.scenario or sorted(TABLE_II)
    noises = args.noise or ["none"]
    for noise in noises:
        parse_noise(noise)  # refuses a bad spec before any work
    flights = []
    for s in scenarios:
        if s not in TABLE_II:
            raise ConfigError(f"scenario {s} must be one of {sorted(TABLE_II)}")
        runs = range(1, len(TABLE_II[s][1]) + 1)
        chosen = [r for r in (args.run or runs) if r in runs]
        for r in chosen:
            for noise in noises:
                flights.append(
                    Flight(
                        s,
                        r,
                        args.frames,
                        args.seed,
                        noise,
                        args.target_mesh,
                        tuple(args.clutter_mesh),
                        args.every,
                    )
                )
    if not flights:
        raise ConfigError(f"no run of scenarios {scenarios} matches --run {args.run}")
    if args.frames is not None and args.frames < 2:
        raise ConfigError(f"--frames {args.frames} must be >= 2 (a scene is a pair of frames)")
    if args.every > 1 and getattr(args, "via_services", False):
        raise ConfigError(
            f"--every {args.every} samples scenes in-process; --via-services replays whole flights"
        )
    return flights


def _arms(args: argparse.Namespace, config: Any) -> list[Any]:
    from atr.baselines2d import PAIRS  # noqa: PLC0415
    from atr.evaluation.runner import Arm, pair_descriptor  # noqa: PLC0415

    pipelines = args.pipeline or ["gftt-sfm"]
    descriptors = args.descriptor or [config.recognition.descriptor]
    arms = []
    for p in pipelines:
        if p in PAIRS:
            arms.append(Arm(p, pair_descriptor(p)))
        else:  # Arm refuses an unknown pipeline or descriptor with a ConfigError naming it
            arms.extend(Arm(p, d) for d in descriptors)
    return list(dict.fromkeys(arms))


def plan(args: argparse.Namespace) -> Plan:
    """Resolve the configuration, flights and arms of an invocation."""
    from atr.config import load_config  # noqa: PLC0415
    from atr.evaluation.io import code_version  # noqa: PLC0415

    overrides = list(args.overrides)
    if args.target_mesh:
        overrides.append(
            f"pipeline.target_meshes=[{json.dumps(str(Path(args.target_mesh).resolve()))}]"
        )
    config = load_config(None, overrides)
    return Plan(
        config,
        overrides,
        _flights(args),
        _arms(args, config),
        code_version(),
        args.results,
        config.baselines2d,
    )


def _effective(plan_: Plan, arm: Any) -> dict[str, Any]:
    from atr.config import to_dict  # noqa: PLC0415
    from atr.evaluation.runner import arm_config  # noqa: PLC0415

    data: dict[str, Any] = {"atr": to_dict(arm_config(plan_.config, arm))}
    if arm.is_2d:
        data["baseline2d"] = plan_.b2d
    return data


def _key(plan_: Plan, flight: Any, arm: Any, via_services: bool) -> str:
    from atr.evaluation.io import run_key  # noqa: PLC0415

    return run_key(
        flight,
        arm,
        _effective(plan_, arm) | {"via_services": via_services and not arm.is_2d},
        plan_.version,
    )


# ------------------------------------------------------------------------------------------- templates


def _templates_3d(plan_: Plan) -> None:
    """Build the templates of every target per descriptor, exactly as template_store serves them."""
    from atr.evaluation.runner import arm_config  # noqa: PLC0415
    from services.atr_matcher.main import template_from_message  # noqa: PLC0415
    from services.template_store.main import TemplateStore  # noqa: PLC0415

    for arm in plan_.arms:
        if arm.is_2d or arm.descriptor in plan_.templates_3d:
            continue
        config = arm_config(plan_.config, arm)
        store = TemplateStore(config, REPO / "templates")
        templates = [
            template_from_message(store.message(name, arm.descriptor)) for name in store.meshes
        ]
        plan_.templates_3d[arm.descriptor] = templates
        target = next((t for t in templates if t.target == plan_.flights[0].target), templates[0])
        kb = (target.descriptors.nbytes + target.keypoints_m.nbytes) / 1024
        plan_.storage_kb[("3d", arm.descriptor)] = kb


def _templates_2d(plan_: Plan) -> None:
    import pickle  # noqa: PLC0415

    from atr.baselines2d import crop_template_views, describe_templates, template_storage_bytes  # noqa: PLC0415
    from atr.evaluation.io import jsonable, run_key  # noqa: PLC0415
    from atr.evaluation.runner import Arm  # noqa: PLC0415
    from atr.io.mesh import load_mesh  # noqa: PLC0415

    pairs = [a.pipeline for a in plan_.arms if a.is_2d]
    if not pairs:
        return
    f0 = plan_.flights[0]
    key = run_key(
        replace(
            f0,
            scenario=plan_.b2d.template_scenario,
            run=plan_.b2d.template_run,
            frames=None,
            noise="none",
        ),
        Arm("2d-1", "gftt+freak"),
        {"sim": jsonable(plan_.config.sim), "b2d": jsonable(plan_.b2d)},
        plan_.version,
    )
    path = plan_.results / "cache" / f"views2d-{key}.pickle"
    if path.exists():
        views = pickle.loads(path.read_bytes())
    else:
        _log(
            f"cropping the 12 2D templates from scenario {plan_.b2d.template_scenario} run "
            f"{plan_.b2d.template_run} (seed {f0.seed})"
        )
        views = crop_template_views(
            f0.seed,
            plan_.config.sim,
            plan_.b2d,
            target_mesh=load_mesh(f0.target_mesh) if f0.target_mesh else None,
            target_name=f0.target if f0.target_mesh else None,
            clutter_meshes=tuple(load_mesh(p) for p in f0.clutter_meshes),
        )
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(views))
    for pair in pairs:
        plan_.templates_2d[pair] = describe_templates(views, pair, plan_.b2d)
        plan_.storage_kb[("2d", pair)] = template_storage_bytes(plan_.templates_2d[pair]) / 1024


def _storage_key(arm: Any) -> tuple[str, str]:
    return ("2d", arm.pipeline) if arm.is_2d else ("3d", arm.descriptor)


def _reuse_extra(plan_: Plan, flight: Any, arm: Any, run_file: Path) -> None:
    """A reused result's template storage and reference time, from its run file: templates are only built
    for runs to do, so an invocation whose results are all current would otherwise report none.
    """
    extra = json.loads(run_file.read_text()).get("extra", {})
    if extra.get("storage_kb") is not None:
        plan_.storage_kb.setdefault(_storage_key(arm), extra["storage_kb"])
    if extra.get("reference_ms") is not None:
        plan_.reference_ms.setdefault(flight, extra["reference_ms"])


# ------------------------------------------------------------------------------------------- running


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _work_in_process(
    flight: Any, arms: list[Any], config: Any, templates_3d: dict, templates_2d: dict, b2d: Any
) -> tuple[dict[Any, list[Any]], float]:
    """One flight through every arm, in a worker process; and the reference workload's time there."""
    from atr.evaluation.runner import run_flight  # noqa: PLC0415
    from atr.evaluation.timing import reference_workload_ms  # noqa: PLC0415

    reference_ms = reference_workload_ms()
    return run_flight(flight, arms, config, templates_3d, templates_2d, b2d), reference_ms


def _share_the_cores(workers: int) -> None:
    """Give a worker its share of the machine's cores (one of ``workers``) for its compiled and OpenCV
    threads.

    Every worker would otherwise start a thread per core for each parallel loop (numba's descriptors and
    neighbour searches, OpenCV's semi-global matching): with two workers on two cores the threads of one
    wait for the other's, and a scene took 1.2-1.5 x its one-worker time (docs/performance.md). The
    thread count changes no result: each loop's iterations are independent, and OpenCV's matcher gives
    the same disparities with 1-8 threads.
    """
    import cv2  # noqa: PLC0415
    import numba  # noqa: PLC0415

    threads = max(1, (os.cpu_count() or 1) // workers)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    cv2.setNumThreads(threads)


def _work_via_services(
    flight: Any, arms: list[Any], plan_: Plan, workdir: Path
) -> dict[Any, list[Any]]:
    """Run one flight: `atr simulate`, then `atr run` per 3D arm; 2D arms in-process on it."""
    from atr.evaluation.runner import arm_overrides, flight_frames, run_flight  # noqa: PLC0415
    from bus.pipeline import run_recording  # noqa: PLC0415
    from bus.recording import write_messages  # noqa: PLC0415
    from services.sensor_source.main import frame_messages  # noqa: PLC0415

    workdir.mkdir(parents=True, exist_ok=True)
    stem = f"s{flight.scenario}r{flight.run}-{flight.noise.replace(':', '')}-seed{flight.seed}"
    recording = workdir / f"{stem}.mcap"
    lidar = any(a.pipeline == "lidar" for a in arms)
    frames = flight_frames(flight, plan_.config, lidar)

    def messages():  # noqa: ANN202
        for index, frame in enumerate(frames):
            yield from frame_messages(
                frame,
                "uav1",
                flight.scenario,
                flight.run,
                flight.seed,
                index == 0 or plan_.config.sim.nav_fix_every_frame,
                plan_.config.sim.present_min_visible_fraction,
            )

    write_messages(recording, messages())
    out: dict[Any, list[Any]] = {}
    for arm in arms:
        if arm.is_2d:
            continue
        result_path = workdir / f"{stem}-{arm.pipeline}-{arm.descriptor}.mcap"
        result = run_recording(
            recording, result_path, overrides=plan_.overrides + arm_overrides(arm)
        )
        if result.failures:
            from atr.errors import AtrError  # noqa: PLC0415

            raise AtrError(
                f"service graph failed on {stem} ({arm.pipeline}/{arm.descriptor}): "
                f"{result.failures}; logs in {result.log_dir}"
            )
        out[arm] = recorded_scenes(result_path, plan_.config.sfm.pair_gap_frames)
    two_d = [a for a in arms if a.is_2d]
    if two_d:
        out |= run_flight(
            flight,
            two_d,
            plan_.config,
            plan_.templates_3d,
            plan_.templates_2d,
            plan_.b2d,
            frames=recorded_frames(recording),
        )
    return out


def recorded_scenes(path: Path, gap: int, uav: str = "uav1") -> list[Any]:
    """Read a recorded run's SceneRecords: truth, Detections and CameraPose by stamp_ns, Timing times."""
    from mcap.reader import make_reader  # noqa: PLC0415

    from bus import codec, keys  # noqa: PLC0415
    from bus.clouds import cloud_points  # noqa: PLC0415
    from cli.flight_report import scene_record  # noqa: PLC0415

    truth: dict[int, dict] = {}
    detections: dict[int, dict] = {}
    stages: dict[int, dict[str, float]] = {}
    clouds: dict[int, int] = {}
    camera_pose: dict[int, dict] = {}
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            topic = channel.topic
            if topic == keys.truth(uav):
                data = codec.unpack(message.data)
                truth[data["stamp_ns"]] = data
            elif topic == keys.detections(uav):
                data = codec.unpack(message.data)
                detections[data["stamp_ns"]] = data
            elif topic in (keys.sfm_cloud(uav), keys.lidar(uav)):
                data = codec.unpack(message.data)
                clouds[data["stamp_ns"]] = len(cloud_points(data))
            elif topic == keys.camera_pose(uav):
                data = codec.unpack(message.data)
                camera_pose.setdefault(data["stamp_ns"], data)
            elif topic.endswith("/timing") and ("/sfm/" in topic or "/atr_matcher/" in topic):
                data = codec.unpack(message.data)
                prefix = "sfm_" if "/sfm/" in topic else ""
                into = stages.setdefault(data["stamp_ns"], {})
                for name, ms in data["stages_ms"].items():
                    if name != "total":
                        into[prefix + name] = float(ms)
    records = []
    for stamp in sorted(truth):
        if truth[stamp]["frame_seq"] < gap:
            continue
        st = stages.get(stamp, {})
        records.append(
            scene_record(
                truth[stamp],
                detections.get(stamp),
                camera_pose.get(stamp),
                time_ms=sum(st.values()) if st else float("nan"),
                stages_ms=st,
                cloud_points=clouds.get(stamp, 0),
            )
        )
    return records


def recorded_frames(path: Path, uav: str = "uav1") -> list[Any]:
    """SensorFrames rebuilt from a recording's image and truth messages (for the 2D baseline)."""
    import numpy as np  # noqa: PLC0415
    from mcap.reader import make_reader  # noqa: PLC0415

    from atr.sim.flight import SensorFrame, TargetTruth  # noqa: PLC0415
    from bus import codec, keys  # noqa: PLC0415

    truth: dict[int, dict] = {}
    images: dict[int, dict] = {}
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(
            topics=[keys.truth(uav), keys.image(uav)], log_time_order=False
        ):
            data = codec.unpack(message.data)
            (truth if channel.topic == keys.truth(uav) else images)[data["stamp_ns"]] = data
    empty = np.zeros((0, 3))
    return [
        SensorFrame(
            seq=int(images[s]["frame_seq"]),
            stamp_ns=s,
            image=np.asarray(images[s]["data"]),
            K=np.asarray(images[s]["K"]),
            T_world_cam=np.asarray(truth[s]["T_world_cam"]),
            imu_t_ns=np.zeros(0, np.int64),
            gyro_radps=empty,
            accel_mps2=empty,
            T_world_imu=np.eye(4),
            v_world_imu_mps=np.zeros(3),
            lidar_points_m=None,
            targets=[
                TargetTruth(t["name"], np.asarray(t["T_world_target"]), t["visible_fraction"])
                for t in truth[s]["targets"]
            ],
        )
        for s in sorted(images)
        if s in truth
    ]


def execute(
    plan_: Plan,
    *,
    jobs: int = 1,
    via_services: bool = False,
    force: bool = False,
) -> dict[tuple[Any, Any], list[Any]]:
    """Compute (or load) every (flight, arm) result of a plan.

    Returns:
        (flight, arm) -> SceneRecords.

    """
    from atr.evaluation.io import load_run, save_run  # noqa: PLC0415
    from atr.evaluation.timing import reference_workload_ms  # noqa: PLC0415

    runs_dir = plan_.results / "runs"
    results: dict[tuple[Any, Any], list[Any]] = {}
    todo: dict[Any, list[Any]] = {}
    keys: dict[tuple[Any, Any], str] = {}
    for flight in plan_.flights:
        for arm in plan_.arms:
            key = keys[(flight, arm)] = _key(plan_, flight, arm, via_services)
            records = None if force else load_run(runs_dir / f"{key}.json", key)
            if records is None:
                todo.setdefault(flight, []).append(arm)
            else:
                results[(flight, arm)] = records
                _reuse_extra(plan_, flight, arm, runs_dir / f"{key}.json")
    total = len(plan_.flights) * len(plan_.arms)
    _log(
        f"atr eval: {total} runs ({len(plan_.flights)} flights x {len(plan_.arms)} pipelines/descriptors), "
        f"{total - sum(map(len, todo.values()))} current results reused, code {plan_.version}"
    )
    if not todo:
        return results
    _templates_3d(plan_)
    _templates_2d(plan_)
    started = time.monotonic()
    done = 0

    def finish(flight: Any, out: dict[Any, list[Any]], reference_ms: float) -> None:
        nonlocal done
        plan_.reference_ms[flight] = reference_ms
        for arm, records in out.items():
            save_run(
                runs_dir / f"{keys[(flight, arm)]}.json",
                flight,
                arm,
                keys[(flight, arm)],
                records,
                {
                    "storage_kb": plan_.storage_kb.get(_storage_key(arm)),
                    "reference_ms": reference_ms,
                },
            )
            results[(flight, arm)] = records
        done += 1
        elapsed = time.monotonic() - started
        eta = elapsed / done * (len(todo) - done)
        bar = "#" * (20 * done // len(todo))
        _log(
            f"[{bar:<20}] {done}/{len(todo)} flights  scenario {flight.scenario} run {flight.run} "
            f"noise {flight.noise}: {len(out)} runs, {elapsed:.0f} s elapsed, ~{eta:.0f} s left"
        )

    if via_services:
        workdir = plan_.results / "services"
        for flight, arms in todo.items():
            reference_ms = reference_workload_ms()
            finish(flight, _work_via_services(flight, arms, plan_, workdir), reference_ms)
        return results
    if jobs <= 1:
        for flight, arms in todo.items():
            finish(
                flight,
                *_work_in_process(
                    flight, arms, plan_.config, plan_.templates_3d, plan_.templates_2d, plan_.b2d
                ),
            )
        return results
    # spawn, not fork: the parent already runs OpenMP/numba threads (template building), and a fork of such a
    # process is unsafe (GNU OpenMP terminates it).
    with ProcessPoolExecutor(
        max_workers=jobs,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_share_the_cores,
        initargs=(min(jobs, len(todo)),),  # fewer flights than jobs: fewer workers share the cores
    ) as pool:
        pending = {
            pool.submit(
                _work_in_process,
                flight,
                arms,
                plan_.config,
                plan_.templates_3d,
                plan_.templates_2d,
                plan_.b2d,
            ): flight
            for flight, arms in todo.items()
        }
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                finish(pending.pop(future), *future.result())
    return results


# ------------------------------------------------------------------------------------------- tables

NOT_ON_A_VEHICLE = "elsewhere"


def flight_vehicles(flight: Any, sim_config: Any) -> tuple[list[str], Any, Any]:
    """The flight's non-target vehicles (names, (V, 3) positions, (V,) radii), from its world rebuilt
    without rendering (about a second; the same world `simulate_flight` renders for it).
    """
    import numpy as np  # noqa: PLC0415

    from atr.io.mesh import load_mesh  # noqa: PLC0415
    from atr.sim.scenarios import scenario as preset  # noqa: PLC0415
    from atr.sim.world import build_world  # noqa: PLC0415

    world = build_world(
        preset(flight.scenario, flight.run),
        flight.seed,
        target_mesh=load_mesh(flight.target_mesh) if flight.target_mesh else None,
        target_name=flight.target,
        clutter_meshes=[load_mesh(p) for p in flight.clutter_meshes],
        config=sim_config,
    )
    vehicles = world.vehicles
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
    from atr.evaluation.metrics import vehicle_under  # noqa: PLC0415

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


def rows(plan_: Plan, results: dict[tuple[Any, Any], list[Any]]) -> tuple[list[dict], list[dict]]:
    """The contract rows (results.json) and the detailed rows (details.json) of every run."""
    import numpy as np  # noqa: PLC0415

    from atr.evaluation.io import jsonable  # noqa: PLC0415
    from atr.evaluation.scoring import summarise  # noqa: PLC0415
    from atr.sim.scenarios import scenario as preset  # noqa: PLC0415

    contract, details = [], []
    worlds: dict[Any, tuple[list[str], Any, Any]] = {}
    for flight in plan_.flights:
        world_key = replace(flight, noise="none")  # noise settings share their flight's world
        for arm in plan_.arms:
            records = results[(flight, arm)]
            s = summarise(records, flight.target, plan_.config.sim.present_min_visible_fraction)
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
            }
            sc = preset(flight.scenario, flight.run)
            storage = plan_.storage_kb.get(_storage_key(arm))
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
    from atr.config import to_dict  # noqa: PLC0415
    from atr.evaluation.io import jsonable  # noqa: PLC0415

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
                    "command": ["atr", "eval", *argv],
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


def run(args: argparse.Namespace) -> int:
    """Plan, compute what is missing, score, write."""
    plan_ = plan(args)
    results = execute(plan_, jobs=args.jobs, via_services=args.via_services, force=args.force)
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
            f"{r['scenario']:>4} {r['run']:>3} {r['pipeline']:<9} {r['descriptor']:<11} {r['noise']:<11} "
            f"{r['tp']:>4} {r['fp']:>4} {r['fn']:>4} {f1:>6} {te:>7} {ms:>9}"
        )
    print(f"results in {out}")
    return 0
