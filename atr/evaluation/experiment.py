"""The paper's experiments (§III) as a plan of flights x arms, computed or loaded from the run cache.

`plan(request)` resolves a `Request` (what `atr eval` asks for) into flights, arms and the effective
configuration; `execute(plan)` computes every (flight, arm) result that is not current in the cache, in-process
(the services' functions, same seeds: identical detections; optionally on Dask workers) or through the real
service graph (`bus.evaluation`, handed in by the caller: the bus is not this package's to import), and returns each run's SceneRecords.
"""

from __future__ import annotations

import json
import os
import pickle
import queue
import time
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

from atr.baselines2d import (
    PAIRS,
    crop_template_views,
    describe_templates,
    template_storage_bytes,
)
from atr.config import AtrConfig, load_config, to_dict
from atr.errors import ConfigError
from atr.evaluation.io import code_version, jsonable, load_run, run_key, save_run
from atr.evaluation.runner import (
    DEFAULT_TARGET,
    Arm,
    Flight,
    SceneRecord,
    arm_config,
    flight_frames,
    pair_descriptor,
    run_flight,
)
from atr.evaluation.timing import reference_workload_ms
from atr.io.mesh import load_mesh, mesh_name, resolve_source
from atr.recognition.template import message_storage_bytes, template_from_message
from atr.scaleout import dask_client, host_slots, report, task_slots
from atr.sim.noise import parse_noise
from atr.sim.scenarios import TABLE_II
from atr.sim.scenarios import scenario as scenario_preset
from atr.sim.vehicles import VEHICLES
from atr.template_store import TemplateStore

REPO = Path(__file__).resolve().parents[2]
# Runs a flight's 3D arms through the service graph: (flight, arms, plan, work folder) -> records per arm.
ViaServices = Callable[["Flight", list["Arm"], "Plan", Path], dict["Arm", list["SceneRecord"]]]
Progress = Callable[[str], None]


class ArmProgress(Protocol):
    """Where `execute` reports the scenes each arm computes (a display with a bar and an ETA per arm)."""

    def start(self, scenes: Mapping[Arm, int]) -> None:
        """The scenes each arm will compute in this invocation, before the first is computed."""

    def advance(self, arm: Arm, scenes: int) -> None:
        """``scenes`` more scenes of ``arm`` computed."""


class _NoArmProgress:
    """The display of a caller that wants none."""

    def start(self, scenes: Mapping[Arm, int]) -> None:
        del scenes

    def advance(self, arm: Arm, scenes: int) -> None:
        del arm, scenes


@dataclass(frozen=True)
class Request:
    """What an evaluation asks for (`atr eval`'s options); empty selections mean the defaults."""

    scenarios: tuple[int, ...] = ()
    """Table II scenarios (default all)."""
    runs: tuple[int, ...] = ()
    """Runs within each scenario (default all)."""
    frames: int | None = None
    """Only the first N frames of each run."""
    every: int = 1
    """Only every K-th scene of each run."""
    pipelines: tuple[str, ...] = ("gftt-sfm",)
    """gftt-sfm, surf-sfm, sgm-sfm, lidar, 2d-1 .. 2d-4."""
    descriptors: tuple[str, ...] = ()
    """3D descriptors of the 3D pipelines (default the configuration's)."""
    noises: tuple[str, ...] = ("none",)
    """none, shot, gaussian:10, gaussian:30."""
    seed: int = 0
    """World seed."""
    target_mesh: str | None = None
    """Mesh file of the target (its template and its world)."""
    clutter_meshes: tuple[str, ...] = ()
    """Extra confuser meshes."""
    targets: tuple[str, ...] = ()
    """Vehicles of the family evaluated in turn as the target, each with the rest of the family as
    confusers, in its world and among the templates (held-out targets, docs/evaluation/protocol.md);
    empty: the one target of ``target_mesh``."""
    overrides: tuple[str, ...] = ()
    """`group.field=value` configuration overrides."""
    results: Path = REPO / "results"
    """Results folder (the run cache lives in its runs/ and cache/)."""
    via_services: bool = False
    """Whether the 3D pipelines run through the real service graph."""


@dataclass
class Plan:
    """What an invocation evaluates."""

    config: AtrConfig
    overrides: list[str]
    flights: list[Flight]
    arms: list[Arm]
    version: str
    results: Path
    b2d: Any  # Baseline2dConfig
    templates_3d: dict[str, list[Any]] = field(default_factory=dict)
    templates_2d: dict[str, list[Any]] = field(default_factory=dict)
    storage_kb: dict[tuple[str, ...], float] = field(default_factory=dict)
    reference_ms: dict[Flight, float] = field(default_factory=dict)  # the workload's time


def _flights(request: Request) -> list[Flight]:
    scenarios = list(request.scenarios) or sorted(TABLE_II)
    for noise in request.noises:
        parse_noise(noise)  # refuses a bad spec before any work
    flights = []
    for s in scenarios:
        if s not in TABLE_II:
            raise ConfigError(f"scenario {s} must be one of {sorted(TABLE_II)}")
        runs = range(1, len(TABLE_II[s][1]) + 1)
        for r in [r for r in (request.runs or runs) if r in runs]:
            flights.extend(
                Flight(s, r, request.frames, request.seed, noise, target, clutter, request.every)
                for target, clutter in _target_choices(request)
                for noise in request.noises
            )
    if not flights:
        raise ConfigError(f"no run of scenarios {scenarios} matches --run {list(request.runs)}")
    if request.frames is not None and request.frames < 2:
        raise ConfigError(f"--frames {request.frames} must be >= 2 (a scene is a pair of frames)")
    if request.every > 1 and request.via_services:
        raise ConfigError(
            f"--every {request.every} samples scenes in-process; --via-services replays whole flights"
        )
    return flights


WORLD_CONFUSERS: tuple[str, ...] = ("ifv", "truck6x6")
"""The confusers every simulated world holds besides the target (atr.sim.world)."""


def _target_choices(request: Request) -> list[tuple[str | None, tuple[str, ...]]]:
    """(target mesh source, extra confusers) of each evaluated target: the request's one target, or
    each of ``request.targets`` with every other vehicle of the family (the T-72 as None, the default
    target, so that its flights are the reported evaluation's whenever the confusers are).
    """
    if not request.targets:
        return [(request.target_mesh, request.clutter_meshes)]
    if request.target_mesh is not None:
        raise ConfigError(
            f"give --targets or --target/--target-mesh {request.target_mesh}, not both"
        )
    unknown = [t for t in request.targets if t not in VEHICLES]
    if unknown:
        raise ConfigError(f"--targets {', '.join(unknown)}: expected vehicles of {list(VEHICLES)}")
    if any(pipeline in PAIRS for pipeline in request.pipelines):
        raise ConfigError(
            "--targets evaluates the 3D pipelines; the 2D baseline crops its templates from one "
            "target's flight"
        )
    choices = []
    for target in dict.fromkeys(request.targets):
        others = tuple(v for v in VEHICLES if v not in (target, *WORLD_CONFUSERS))
        choices.append(
            (None if target == DEFAULT_TARGET else target, others + request.clutter_meshes)
        )
    return choices


def _arms(request: Request, config: AtrConfig) -> list[Arm]:
    descriptors = request.descriptors or (config.recognition.descriptor,)
    arms = []
    for p in request.pipelines:
        if p in PAIRS:
            arms.append(Arm(p, pair_descriptor(p)))
        else:  # Arm refuses an unknown pipeline or descriptor with a ConfigError naming it
            arms.extend(Arm(p, d) for d in descriptors)
    return list(dict.fromkeys(arms))


def plan(request: Request) -> Plan:
    """Resolve the configuration, flights and arms of a request.

    Raises:
        ConfigError: an unknown scenario, pipeline, descriptor, noise or configuration field, or
            options that do not go together.

    """
    overrides = list(request.overrides)
    if request.targets:  # every vehicle of the family is a template: the target and its confusers
        overrides.append(f"pipeline.targets={json.dumps(list(VEHICLES))}")
    if request.target_mesh:
        overrides.append(
            f"pipeline.target_meshes=[{json.dumps(resolve_source(request.target_mesh))}]"
        )
    config = load_config(None, overrides)
    return Plan(
        config,
        overrides,
        _flights(request),
        _arms(request, config),
        code_version(),
        request.results,
        config.baselines2d,
    )


def _effective(plan_: Plan, arm: Arm) -> dict[str, Any]:
    data: dict[str, Any] = {"atr": to_dict(arm_config(plan_.config, arm))}
    if arm.is_2d:
        data["baseline2d"] = plan_.b2d
    return data


def _key(plan_: Plan, flight: Flight, arm: Arm, via_services: bool) -> str:
    return run_key(
        flight,
        arm,
        _effective(plan_, arm) | {"via_services": via_services and not arm.is_2d},
        plan_.version,
    )


# ------------------------------------------------------------------------------------------- templates


def _templates_3d(plan_: Plan) -> None:
    """Build the templates of every target per descriptor, exactly as template_store serves them."""
    for arm in plan_.arms:
        if arm.is_2d or arm.descriptor in plan_.templates_3d:
            continue
        config = arm_config(plan_.config, arm)
        store = TemplateStore(config, REPO / "templates")
        messages = {name: store.message(name, arm.descriptor) for name in store.meshes}
        plan_.templates_3d[arm.descriptor] = [template_from_message(m) for m in messages.values()]
        for name, message in messages.items():
            plan_.storage_kb[("3d", arm.descriptor, name)] = message_storage_bytes(message) / 1024


_VIEW_FIELDS = (
    "n_templates",
    "template_scenario",
    "template_run",
    "template_scales",
    "scaled_template_context_px",
    "crop_margin_frac",
    "min_template_visible_fraction",
)
"""The 2D baseline's settings its template crops depend on (the cache key of the crops: changing a
matching threshold reuses them)."""


def _view_fields(b2d: Any) -> dict[str, Any]:
    return {name: jsonable(getattr(b2d, name)) for name in _VIEW_FIELDS}


def _templates_2d(plan_: Plan, progress: Progress) -> None:
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
        {"sim": jsonable(plan_.config.sim), "views": _view_fields(plan_.b2d)},
        plan_.version,
    )
    path = plan_.results / "cache" / f"views2d-{key}.pickle"
    if path.exists():
        views = pickle.loads(path.read_bytes())
    else:
        sc = scenario_preset(plan_.b2d.template_scenario, plan_.b2d.template_run)
        progress(
            f"cropping the {plan_.b2d.n_templates} 2D templates x scales "
            f"{list(plan_.b2d.template_scales)} from scenario {sc.scenario} run {sc.run} "
            f"({sc.obliquity_deg:.0f} deg obliquity, seed {f0.seed})"
        )
        views = crop_template_views(
            f0.seed,
            plan_.config.sim,
            plan_.b2d,
            target_mesh=load_mesh(f0.target_mesh) if f0.target_mesh else None,
            target_name=f0.target if f0.target_mesh else None,
            clutter_meshes=tuple((mesh_name(p), load_mesh(p)) for p in f0.clutter_meshes),
        )
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(views))
    for pair in pairs:
        plan_.templates_2d[pair] = describe_templates(views, pair, plan_.b2d)
        plan_.storage_kb[("2d", pair)] = template_storage_bytes(plan_.templates_2d[pair]) / 1024


def storage_key(arm: Arm, flight: Flight) -> tuple[str, ...]:
    """The key in `Plan.storage_kb` of the template a flight's arm looks for: (2d, pair), whose templates
    are cropped from one flight whatever the target, or (3d, descriptor, target).
    """
    return ("2d", arm.pipeline) if arm.is_2d else ("3d", arm.descriptor, flight.target)


def _reuse_extra(plan_: Plan, flight: Flight, arm: Arm, run_file: Path) -> None:
    """A reused result's template storage and reference time, from its run file: templates are only built
    for runs to do, so an invocation whose results are all current would otherwise report none.
    """
    extra = json.loads(run_file.read_text()).get("extra", {})
    if extra.get("storage_kb") is not None:
        plan_.storage_kb.setdefault(storage_key(arm, flight), extra["storage_kb"])
    if extra.get("reference_ms") is not None:
        plan_.reference_ms.setdefault(flight, extra["reference_ms"])


# ------------------------------------------------------------------------------------------- running


def _silent(text: str) -> None:
    del text


@dataclass(frozen=True)
class _Shared:
    """What every flight's work needs besides its flight and arms (sent to each Dask worker once)."""

    config: AtrConfig
    templates_3d: dict[str, list[Any]]
    templates_2d: dict[str, list[Any]]
    b2d: Any  # Baseline2dConfig
    version: str  # the code version the results are keyed with


def _scenes(flight: Flight, gap: int) -> int:
    """Scenes of a flight (frames that close a pair, sampled by ``flight.every``), without simulating it."""
    n_frames = flight.frames or scenario_preset(flight.scenario, flight.run).n_frames
    return sum(flight.is_scene(seq, gap) for seq in range(n_frames))


def _reporting(
    frames: Iterable[Any], flight: Flight, gap: int, on_scene: Callable[[], None]
) -> Iterator[Any]:
    """The frames, calling ``on_scene`` once every arm has processed a scene: `run_flight` asks for the
    next frame only when it is done with the last one.
    """
    pending = False
    for frame in frames:
        if pending:
            on_scene()
        pending = flight.is_scene(frame.seq, gap)
        yield frame
    if pending:
        on_scene()


def _work(
    flight: Flight, arms: list[Arm], shared: _Shared, on_scene: Callable[[], None]
) -> tuple[dict[Arm, list[SceneRecord]], float]:
    """One flight through every arm; and the reference workload's time, taken just before in the same
    process (a worker's own, on a cluster).
    """
    reference_ms = reference_workload_ms()
    config = shared.config
    # the frames run_flight simulates itself (same call), passed in only to see each scene finish
    frames = flight_frames(flight, config, any(a.pipeline == "lidar" for a in arms))
    out = run_flight(
        flight,
        arms,
        config,
        shared.templates_3d,
        shared.templates_2d,
        shared.b2d,
        frames=_reporting(frames, flight, config.sfm.pair_gap_frames, on_scene),
    )
    return out, reference_ms


def _share_the_cores(workers: int) -> None:
    """Give a worker its share of the machine's cores (one of ``workers``) for its compiled and OpenCV
    threads.

    Every worker would otherwise start a thread per core for each parallel loop (numba's descriptors and
    neighbour searches, OpenCV's semi-global matching): with two workers on two cores the threads of one
    wait for the other's, and a scene took 1.2-1.5 x its one-worker time (docs/performance.md). The
    thread count changes no result: each loop's iterations are independent, and OpenCV's matcher gives
    the same disparities with 1-8 threads. numba's count is the calling thread's own: call it in the
    thread that does the work.
    """
    import cv2
    import numba

    threads = max(1, (os.cpu_count() or 1) // workers)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    cv2.setNumThreads(threads)


def _work_on_worker(
    flight: Flight,
    arms: list[Arm],
    shared: _Shared,
    slots: dict[str, int],
    topic: str,
    index: int,
) -> tuple[dict[Arm, list[SceneRecord]], float]:
    """A Dask task: one flight on its share of its host's cores, each finished scene sent to the client
    as event ``index`` on ``topic``.

    Raises:
        ConfigError: the worker's `atr` sources are not the ones the results are keyed with.

    """
    here = code_version()
    if (
        here != shared.version
    ):  # a cluster's worker with another checkout would mix code under one key
        raise ConfigError(
            f"a Dask worker runs atr code {here}, this evaluation {shared.version}: "
            "every worker needs the same checkout"
        )
    _share_the_cores(task_slots(slots))
    return _work(flight, arms, shared, lambda: report(topic, index))


@dataclass
class _Runs:
    """The runs an invocation computes, and what it has computed so far: each flight's finished arms are
    saved to the run cache as they come, with a line of progress; each finished scene moves its arms' bars.
    """

    plan: Plan
    keys: dict[tuple[Flight, Arm], str]
    todo: dict[Flight, list[Arm]]
    results: dict[tuple[Flight, Arm], list[SceneRecord]]
    progress: Progress
    bars: ArmProgress
    started: float = field(default_factory=time.monotonic)
    done: int = 0
    counted: dict[Flight, int] = field(default_factory=dict)  # scenes shown on the bars
    finished: set[Flight] = field(default_factory=set)

    @property
    def shared(self) -> _Shared:
        """The plan's configuration and templates, as every flight's work takes them."""
        p = self.plan
        return _Shared(p.config, p.templates_3d, p.templates_2d, p.b2d, p.version)

    def start(self) -> None:
        """Show the scenes to compute per arm, and start the clock."""
        gap = self.plan.config.sfm.pair_gap_frames
        scenes: dict[Arm, int] = {arm: 0 for arm in self.plan.arms}
        for flight, arms in self.todo.items():
            for arm in arms:
                scenes[arm] += _scenes(flight, gap)
        self.bars.start({arm: n for arm, n in scenes.items() if n})
        self.started = time.monotonic()

    def scene_done(self, flight: Flight) -> None:
        """One more scene of ``flight`` computed by every arm it runs (a late report is ignored)."""
        if flight in self.finished:
            return
        self.counted[flight] = self.counted.get(flight, 0) + 1
        for arm in self.todo[flight]:
            self.bars.advance(arm, 1)

    def finish(
        self, flight: Flight, out: dict[Arm, list[SceneRecord]], reference_ms: float
    ) -> None:
        """Keep and save one flight's records, and say how far the invocation is."""
        self.plan.reference_ms[flight] = reference_ms
        for arm, records in out.items():
            key = self.keys[(flight, arm)]
            save_run(
                self.plan.results / "runs" / f"{key}.json",
                flight,
                arm,
                key,
                records,
                {
                    "storage_kb": self.plan.storage_kb.get(storage_key(arm, flight)),
                    "reference_ms": reference_ms,
                },
            )
            self.results[(flight, arm)] = records
            unreported = len(records) - self.counted.get(
                flight, 0
            )  # late, or never sent (services)
            if unreported:
                self.bars.advance(arm, unreported)
        self.finished.add(flight)
        self.done += 1
        elapsed = time.monotonic() - self.started
        eta = elapsed / self.done * (len(self.todo) - self.done)
        bar = "#" * (20 * self.done // len(self.todo))
        self.progress(
            f"[{bar:<20}] {self.done}/{len(self.todo)} flights  scenario {flight.scenario} run "
            f"{flight.run} noise {flight.noise}: {len(out)} runs, {elapsed:.0f} s elapsed, "
            f"~{eta:.0f} s left"
        )


def execute(
    plan_: Plan,
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    via_services: ViaServices | None = None,
    force: bool = False,
    progress: Progress = _silent,
    bars: ArmProgress | None = None,
) -> dict[tuple[Flight, Arm], list[SceneRecord]]:
    """Compute (or load) every (flight, arm) result of a plan.

    Flights run in this process (``jobs`` 1, no ``scheduler``), or as tasks on Dask (`atr.scaleout`): a
    LocalCluster of ``jobs`` worker processes, or the cluster at ``scheduler``. Each task is one flight
    through every arm, on its share of its host's cores; the records are the same either way, and each
    flight's are saved to the run cache as it finishes (here, where the cache is).

    Args:
        plan_: what to evaluate.
        jobs: local worker processes (flights run in parallel; in-process runs only).
        scheduler: address of a Dask scheduler (``tcp://HOST:8786``) whose workers run the flights.
        via_services: when given (`bus.evaluation.run_via_services`), the 3D arms run through the
            real service graph from recordings, flight by flight, with this function.
        force: recompute runs even when a current result exists.
        progress: called with one line of progress at a time.
        bars: shown the scenes each arm computes, scene by scene (flight by flight via the services).

    Returns:
        (flight, arm) -> SceneRecords.

    Raises:
        SchedulerError: ``scheduler`` did not answer.
        ConfigError: ``jobs`` < 1, or a scheduler with via_services.
        AtrError: the service graph failed on a flight (via_services), or a flight raised one.

    """
    if jobs < 1:
        raise ConfigError(f"--jobs {jobs} must be >= 1")
    if scheduler and via_services is not None:
        raise ConfigError(
            f"--scheduler {scheduler} runs in-process flights on a cluster; "
            "--via-services replays them here through the service graph"
        )
    keys = {
        (flight, arm): _key(plan_, flight, arm, via_services is not None)
        for flight in plan_.flights
        for arm in plan_.arms
    }
    results, todo = _current(plan_, keys, force)
    total = len(plan_.flights) * len(plan_.arms)
    progress(
        f"atr eval: {total} runs ({len(plan_.flights)} flights x {len(plan_.arms)} pipelines/descriptors), "
        f"{total - sum(map(len, todo.values()))} current results reused, code {plan_.version}"
    )
    if not todo:
        return results
    with ExitStack() as stack:
        client = None
        if via_services is None and (scheduler or jobs > 1):
            # before the templates: an unreachable scheduler is said at once
            client = stack.enter_context(dask_client(scheduler, min(jobs, len(todo))))
            progress(_where(client, scheduler, len(todo)))
        _templates_3d(plan_)
        _templates_2d(plan_, progress)
        runs = _Runs(plan_, keys, todo, results, progress, bars or _NoArmProgress())
        if via_services is not None:
            _run_via_services(runs, via_services)
        elif client is None:
            _run_here(runs)
        else:
            _run_on_dask(runs, client)
    return results


def _where(client: Any, scheduler: str | None, flights: int) -> str:
    workers = client.scheduler_info()["workers"]
    threads = sum(int(w["nthreads"]) for w in workers.values())
    where = f"the Dask scheduler {scheduler}" if scheduler else "a Dask LocalCluster"
    return (
        f"{flights} flights on {where}: {len(workers)} worker processes, "
        f"{threads} flights at a time"
    )


def _current(
    plan_: Plan, keys: dict[tuple[Flight, Arm], str], force: bool
) -> tuple[dict[tuple[Flight, Arm], list[SceneRecord]], dict[Flight, list[Arm]]]:
    """The results the run cache holds for the current code and configuration (none when forced), and
    per flight the arms left to compute.
    """
    runs_dir = plan_.results / "runs"
    results: dict[tuple[Flight, Arm], list[SceneRecord]] = {}
    todo: dict[Flight, list[Arm]] = {}
    for (flight, arm), key in keys.items():
        records = None if force else load_run(runs_dir / f"{key}.json", key)
        if records is None:
            todo.setdefault(flight, []).append(arm)
        else:
            results[(flight, arm)] = records
            _reuse_extra(plan_, flight, arm, runs_dir / f"{key}.json")
    return results, todo


def _run_via_services(runs: _Runs, via_services: ViaServices) -> None:
    workdir = runs.plan.results / "services"
    runs.start()
    for flight, arms in runs.todo.items():
        reference_ms = reference_workload_ms()
        runs.finish(flight, via_services(flight, arms, runs.plan, workdir), reference_ms)


def _run_here(runs: _Runs) -> None:
    shared = runs.shared
    runs.start()
    for flight, arms in runs.todo.items():
        runs.finish(flight, *_work(flight, arms, shared, lambda f=flight: runs.scene_done(f)))


def _run_on_dask(runs: _Runs, client: Any) -> None:
    """One task per flight; the client saves each flight's records as its task finishes, and moves the
    bars as the workers report scenes. The plan's templates go to each worker once.
    """
    events: queue.Queue[tuple[str, Any]] = queue.Queue()  # filled from the client's threads
    tag = uuid.uuid4().hex[:8]  # a cluster may serve several evaluations at once
    topic = f"atr-eval-{tag}"
    client.subscribe_topic(topic, lambda event: events.put(("scene", event[1])))
    shared = client.scatter(runs.shared, hash=False)
    slots = host_slots(client)
    flights = list(runs.todo)
    pending: dict[str, Flight] = {}
    for index, (flight, arms) in enumerate(runs.todo.items()):
        future = client.submit(
            _work_on_worker,
            flight,
            arms,
            shared,
            slots,
            topic,
            index,
            key=f"atr-eval-s{flight.scenario}r{flight.run}-{flight.noise}-{index}-{tag}",
            pure=False,
        )
        future.add_done_callback(lambda done: events.put(("done", done)))
        pending[future.key] = flight
    runs.start()
    while pending:
        kind, what = events.get()
        if kind == "scene":
            runs.scene_done(flights[what])
        else:
            runs.finish(pending.pop(what.key), *what.result())
