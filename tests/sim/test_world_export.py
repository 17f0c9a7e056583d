import argparse
import json

import pytest

from atr.errors import InputError
from atr.io.mesh import load_mesh
from atr.sim import VEHICLES, t72
from atr.sim.vehicles import vehicle
from cli import world


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    world.add_arguments(parser)
    return parser.parse_args(["export", *argv])


def test_world_export_writes_every_vehicle_of_the_family(tmp_path):
    assert world.run(_args("--out", str(tmp_path), "--format", "obj")) == 0
    names = sorted(p.name for p in (tmp_path / "vehicles").iterdir())
    assert names == sorted(f"{name}.obj" for name in VEHICLES)
    assert load_mesh(tmp_path / "vehicles" / "t72.obj").n_triangles == t72().n_triangles


def test_world_export_writes_the_vehicles_asked_for(tmp_path):
    args = _args(
        "--out", str(tmp_path), "--format", "stl", "--vehicle", "m109", "--vehicle", "btr80"
    )
    assert world.run(args) == 0
    assert sorted(p.name for p in (tmp_path / "vehicles").iterdir()) == ["btr80.stl", "m109.stl"]
    loaded = load_mesh(tmp_path / "vehicles" / "m109.stl")
    assert loaded.bounds()[1] == pytest.approx(vehicle("m109").bounds()[1], abs=1e-4)


def test_world_export_of_a_world_with_a_chosen_target(tmp_path):
    args = _args(
        "--out",
        str(tmp_path),
        "--vehicle",
        "car",
        "--world",
        "--scenario",
        "3",
        "--run",
        "1",
        "--target",
        "hmmwv",
        "--clutter",
        "t72",
    )
    assert world.run(args) == 0
    meta = json.loads((tmp_path / "world_s3_r1_seed0" / "world.json").read_text())
    assert meta["target_name"] == "hmmwv"
    assert "t72" in {v["name"] for v in meta["vehicles"]}
    target = load_mesh(tmp_path / "world_s3_r1_seed0" / "target.ply")
    assert target.n_triangles == vehicle("hmmwv").n_triangles


def test_world_export_refuses_an_unknown_vehicle_before_writing(tmp_path):
    with pytest.raises(InputError, match="unknown vehicle 'tiger'"):
        world.run(_args("--out", str(tmp_path), "--vehicle", "tiger"))
    assert not (tmp_path / "vehicles").exists()
