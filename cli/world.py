"""Export the simulated world's meshes: the vehicle family (each one's model is also its template's CAD
model) and, optionally, the whole world of one scenario run.

Writes into DIR:
    vehicles/<name>.ply                                   every vehicle of the family (or the --vehicle
                                                          ones), vehicle frame: x forward, z up, metres
    world_s{S}_r{R}_seed{K}/static.ply, target.ply        the run's world (with --world), world frame
    world_s{S}_r{R}_seed{K}/world.json                    target name and pose, sun direction, orbit,
                                                          occluder width, where every vehicle stands

The family: t72, ifv, truck6x6, car, leopard2, m1, m113, btr80, m109, hmmwv, pickup (docs/sim.md,
"Vehicles"). --target/--clutter choose the world's target and extra confusers by name, --target-mesh/
--clutter-mesh from files (FILE[:units=mm,up=y,forward=-z], docs/sim.md).

Examples:
    atr world export --out meshes
    atr world export --out meshes --format obj --vehicle leopard2 --vehicle btr80
    atr world export --out meshes --world --scenario 3 --run 1 --seed 2
    atr world export --out meshes --world --target m1 --clutter t72 --clutter m109

"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cli._args import add_repeatable


def add_vehicle_arguments(parser: argparse.ArgumentParser, mesh_files: bool = False) -> None:
    """`--target NAME` and `--clutter NAME` (vehicles of the family); with mesh_files also
    `--target-mesh FILE` and `--clutter-mesh FILE`.
    """
    parser.add_argument(
        "--target", metavar="NAME", help="vehicle of the family replacing the T-72, e.g. leopard2"
    )
    add_repeatable(parser, "--clutter", "extra confuser vehicle of the family", metavar="NAME")
    if mesh_files:
        parser.add_argument(
            "--target-mesh",
            metavar="FILE",
            help="mesh file replacing the T-72: PLY/OBJ/STL/GLB[:units=mm,up=y,forward=x]",
        )
        add_repeatable(parser, "--clutter-mesh", "extra confuser mesh file", metavar="FILE")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `atr world`."""
    sub = parser.add_subparsers(dest="world_command", metavar="ACTION", required=True)
    exp = sub.add_parser(
        "export",
        help="write vehicle (and world) meshes to a folder",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    exp.add_argument("--out", type=Path, required=True, help="output folder")
    exp.add_argument(
        "--format", choices=("ply", "obj", "stl"), default="ply", help="mesh file format"
    )
    add_repeatable(
        exp, "--vehicle", "export only this vehicle of the family", "all", metavar="NAME"
    )
    exp.add_argument(
        "--world", action="store_true", help="also export the world of one scenario run"
    )
    exp.add_argument("--scenario", type=int, default=1, help="Table II scenario (1, 2, 3)")
    exp.add_argument("--run", type=int, default=3, help="run within the scenario (1-based)")
    exp.add_argument("--seed", type=int, default=0, help="world seed")
    add_vehicle_arguments(exp, mesh_files=True)


def run(args: argparse.Namespace) -> int:
    """Write the meshes; returns 0."""
    from atr.io.mesh import save_mesh, vehicle_sources
    from atr.sim.scenarios import scenario
    from atr.sim.vehicles import VEHICLES, vehicle

    for name in args.vehicle:  # an unknown name or run fails before anything is written
        vehicle(name)
    if args.world:
        scenario(args.scenario, args.run)
    sources = vehicle_sources(args.target, args.target_mesh, args.clutter, args.clutter_mesh)
    out: Path = args.out
    for name in args.vehicle or VEHICLES:
        path = out / "vehicles" / f"{name}.{args.format}"
        save_mesh(vehicle(name), path)
        print(f"wrote {path}")
    if args.world:
        print(f"wrote {_export_world(args, *sources)}")
    return 0


def _export_world(args: argparse.Namespace, target: str | None, clutter: tuple[str, ...]) -> Path:
    from atr.io.mesh import load_mesh, mesh_name, save_mesh
    from atr.sim import build_world, scenario

    sc = scenario(args.scenario, args.run)
    world = build_world(
        sc,
        args.seed,
        target_mesh=load_mesh(target) if target else None,
        target_name=mesh_name(target) if target else None,
        clutter_meshes=[(mesh_name(c), load_mesh(c)) for c in clutter],
    )
    folder = args.out / f"world_s{sc.scenario}_r{sc.run}_seed{args.seed}"
    save_mesh(world.static, folder / f"static.{args.format}")
    save_mesh(world.target, folder / f"target.{args.format}")
    o = world.orbit
    meta = {
        "scenario": sc.scenario,
        "run": sc.run,
        "seed": args.seed,
        "target_name": world.target_name,
        "T_world_target": world.T_world_target.tolist(),
        "sun_dir": world.sun_dir.tolist(),
        "orbit": {
            "center_m": o.center.tolist(),
            "radius_m": o.radius_m,
            "height_m": o.height_m,
            "rate_radps": o.rate_radps,
        },
        "occluder_width_m": world.occluder_width_m,
        "static_triangles": world.static.n_triangles,
        "vehicles": [
            {"name": v.name, "position_m": [float(p) for p in v.position_m], "yaw_rad": v.yaw_rad}
            for v in world.vehicles
        ],
    }
    (folder / "world.json").write_text(json.dumps(meta, indent=2))
    return folder
