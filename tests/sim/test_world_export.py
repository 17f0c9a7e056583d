import argparse

from atr.io.mesh import load_mesh
from atr.sim import t72
from cli import world


def test_world_export_writes_loadable_vehicle_meshes(tmp_path):
    parser = argparse.ArgumentParser()
    world.add_arguments(parser)
    args = parser.parse_args(["export", "--out", str(tmp_path), "--format", "obj"])
    assert world.run(args) == 0
    names = sorted(p.name for p in (tmp_path / "vehicles").iterdir())
    assert names == ["car.obj", "ifv.obj", "t72.obj", "truck6x6.obj"]
    assert load_mesh(tmp_path / "vehicles" / "t72.obj").n_triangles == t72().n_triangles
