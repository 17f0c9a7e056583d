"""The demo flight: simulate a short flight and run the whole service graph over Zenoh, end to end.

Scenario 1 at 30 degrees obliquity (50 m range), about 20 scenes: sensor_source -> pose_integrator -> sfm ->
atr_matcher, with template_store answering and the recorder on. It prints, per scene, what was recognised
where against the simulator's truth, then the flight's F1 (§III-C) and the recording's path.

The SfM is the default arm, dense (semi-global matching), which measures best on held-out targets;
--preset paper flies the paper's sparse GFTT/KLT SfM instead.

The target is the T-72 unless --target names another vehicle of the family or --target-mesh gives a mesh file
(its template is built for the flight); --clutter and --clutter-mesh add confusers (docs/sim.md, "Vehicles").

Examples:
    atr demo
    atr demo --target leopard2 --clutter t72 --clutter m109
    atr demo --preset paper
    atr demo --frames 10 --set recognition.descriptor=fpfh
    atr demo --scenario 2 --run 1 --set sfm.matcher=surf
    atr demo --scenario 3 --set sfm.pair_gap_frames=2

"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from bus.service import add_overrides_argument
from cli.world import add_vehicle_arguments

DEMO_OBLIQUITY_DEG = 30.0
"""Without --run the demo flies the scenario's run at this obliquity (the paper's medium, Table II)."""


def demo_run(scenario: int) -> int:
    """The scenario's run at ``DEMO_OBLIQUITY_DEG`` (scenario 1 and 2: run 3; scenario 3: its only run)."""
    from atr.sim.scenarios import TABLE_II

    # an unknown scenario gets run 1: the sensor source then names the bad scenario
    obliquities = TABLE_II[scenario][1] if scenario in TABLE_II else ()
    return obliquities.index(DEMO_OBLIQUITY_DEG) + 1 if DEMO_OBLIQUITY_DEG in obliquities else 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr demo`."""
    parser.add_argument("--scenario", type=int, default=1)
    parser.add_argument(
        "--run", type=int, default=None, help="default: the scenario's 30 deg obliquity run"
    )
    parser.add_argument(
        "--frames", type=int, default=21, help="frames to fly (scenes = frames - pair gap)"
    )
    parser.add_argument("--seed", type=int, default=0)
    add_vehicle_arguments(parser, mesh_files=True)
    add_overrides_argument(parser)
    parser.add_argument("--out", type=Path, help="recording (default runs/demo-<time>/flight.mcap)")


def vehicle_options(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """The sensor source's arguments and the configuration overrides that fly the chosen target and
    confusers (absolute file paths: the services do not run in the user's folder), and serve the target's
    template.

    Raises:
        InputError: as `atr.io.mesh.vehicle_sources`.

    """
    import json

    from atr.config import load_config
    from atr.io.mesh import parse_source, resolve_source, vehicle_sources

    target, clutter = vehicle_sources(
        args.target, args.target_mesh, args.clutter, args.clutter_mesh
    )
    source_args: list[str] = []
    for flag, source in [("--target-mesh", target)] + [("--clutter-mesh", c) for c in clutter]:
        if source is not None:
            source_args += [flag, resolve_source(source)]
    overrides = list(args.overrides)
    if target is not None:
        pipeline = load_config(None, overrides).pipeline
        if parse_source(target).path is None:  # a vehicle of the family: a template like the T-72's
            if target not in pipeline.targets:
                overrides.append(f"pipeline.targets={json.dumps([*pipeline.targets, target])}")
        else:
            meshes = [*pipeline.target_meshes, resolve_source(target)]
            overrides.append(f"pipeline.target_meshes={json.dumps(meshes)}")
    return source_args, overrides


def run(args: argparse.Namespace) -> int:
    """Fly, print per-scene results and the F1; 0 when every process stayed up."""
    from atr.config import load_config
    from atr.io.mesh import mesh_name
    from bus.launcher import interrupt_on_signals
    from bus.pipeline import check_output, fly_layout
    from cli.flight_report import FlightPrinter, f1_line, summarise, summarise_tracks, track_line

    if args.run is None:
        args.run = demo_run(args.scenario)
    vehicle_args, overrides = vehicle_options(args)
    matcher = load_config(None, overrides).sfm.matcher  # a bad override: refused before anything
    target = (
        mesh_name(args.target or args.target_mesh) if (args.target or args.target_mesh) else "t72"
    )
    # a relative path is the user's, not the services' folder (fly_layout checks the rest first)
    out = check_output(
        args.out or Path("runs") / time.strftime("demo-%Y%m%d-%H%M%S") / "flight.mcap"
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    print(
        f"demo: scenario {args.scenario} run {args.run}, {args.frames} frames, sfm.matcher={matcher}; "
        "starting the services (the first run builds the templates and compiles the kernels: a minute "
        "or two)",
        flush=True,
    )
    printer = FlightPrinter(target)
    with interrupt_on_signals():  # SIGTERM/SIGHUP stop the layout as Ctrl-C does
        result = fly_layout(
            out,
            overrides=overrides,
            source_args=[
                "--scenario",
                str(args.scenario),
                "--run",
                str(args.run),
                "--frames",
                str(args.frames),
                "--seed",
                str(args.seed),
                *vehicle_args,
            ],
            on_session=printer.attach,
        )
    printer.detach()
    counts = summarise(out, target)
    if counts is not None:
        print("\n" + f1_line(counts))
        tracks = summarise_tracks(out, target)
        if tracks is not None:
            print(track_line(tracks))
    print(f"recording: {out}")
    from bus.foxglove_export import export_foxglove

    foxglove_path = out.with_name(out.stem + "-foxglove.mcap")
    export_foxglove(out, foxglove_path)
    print(f"for Foxglove: {foxglove_path}")
    for name, codes in result.failures.items():
        print(
            f"process {name} failed (exit codes {codes}); its log: {result.log_dir / (name + '.log')}"
        )
    return 1 if result.failures else 0
