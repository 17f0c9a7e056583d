"""Export the simulated world's meshes: the vehicle models (the T-72 is also the template store's
CAD model) and, optionally, the whole world of one scenario run.

Writes into DIR:
    vehicles/t72.ply, ifv.ply, truck6x6.ply, car.ply      the vehicle models (vehicle frame: x
    forward, z up)
    world_s{S}_r{R}_seed{K}/static.ply, target.ply        the run's world (with --world), world
    frame
    world_s{S}_r{R}_seed{K}/world.json                    target pose, sun direction, orbit,
    occluder width

Examples:
    atr world export --out meshes
    atr world export --out meshes --format obj
    atr world export --out meshes --world --scenario 3 --run 1 --seed 2

"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


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
    exp.add_argument(
        "--world", action="store_true", help="also export the world of one scenario run"
    )
    exp.add_argument("--scenario", type=int, default=1, help="Table II scenario (1, 2, 3)")
    exp.add_argument("--run", type=int, default=3, help="run within the scenario (1-based)")
    exp.add_argument("--seed", type=int, default=0, help="world seed")


def run(args: argparse.Namespace) -> int:
    """Write the meshes; returns 0."""
    from atr.io.mesh import save_mesh
    from atr.sim import VEHICLES, build_world, scenario

    out: Path = args.out
    for name, make in VEHICLES.items():
        path = out / "vehicles" / f"{name}.{args.format}"
        save_mesh(make(), path)
        print(f"wrote {path}")
    if args.world:
        sc = scenario(args.scenario, args.run)
        world = build_world(sc, args.seed)
        folder = out / f"world_s{sc.scenario}_r{sc.run}_seed{args.seed}"
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
        }
        (folder / "world.json").write_text(json.dumps(meta, indent=2))
        print(f"wrote {folder}")
    return 0
