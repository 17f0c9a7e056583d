"""Mesh sources: vehicles by name, and mesh files with their units, up and forward axes."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

from atr.errors import InputError
from atr.io.mesh import (
    load_mesh,
    mesh_name,
    parse_source,
    resolve_source,
    save_mesh,
    vehicle_sources,
)
from atr.sim.mesh import Mesh
from atr.sim.vehicles import VEHICLES, btr80, vehicle

# file frame -> vehicle frame (x forward, y left, z up) of the files these tests write:
# y-up with x forward: (x, y, z)_file = (x, z, -y); glTF (y up, z forward): (x, y, z)_file = (y, z, x)
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
GLTF = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def _as_file(mesh: Mesh, R_file_vehicle: np.ndarray, scale: float = 1.0) -> Mesh:
    return Mesh(mesh.vertices @ R_file_vehicle.T * scale, mesh.triangles, mesh.material)


def _write_glb(path: Path, mesh: Mesh) -> None:
    """A glTF 2.0 binary file (one mesh, positions and indices), as the specification lays it out."""
    v = np.ascontiguousarray(mesh.vertices, np.float32)
    t = np.ascontiguousarray(mesh.triangles, np.uint32)
    blob = v.tobytes() + t.tobytes()  # both are multiples of 4 bytes
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": v.nbytes, "target": 34962},
            {"buffer": 0, "byteOffset": v.nbytes, "byteLength": t.nbytes, "target": 34963},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": len(v),
                "type": "VEC3",
                "min": v.min(0).tolist(),
                "max": v.max(0).tolist(),
            },
            {"bufferView": 1, "componentType": 5125, "count": t.size, "type": "SCALAR"},
        ],
    }
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    with open(path, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob)))
        f.write(struct.pack("<I4s", len(text), b"JSON") + text)
        f.write(struct.pack("<I4s", len(blob), b"BIN\0") + blob)


def _assert_same_place(loaded: Mesh, expected: Mesh, atol: float = 1e-4) -> None:
    assert loaded.n_triangles == expected.n_triangles
    for got, want in zip(loaded.bounds(), expected.bounds(), strict=True):
        np.testing.assert_allclose(got, want, atol=atol)


def test_a_vehicle_name_is_the_vehicle_with_its_paints():
    mesh = load_mesh("btr80")
    assert mesh.vertices.tobytes() == btr80().vertices.tobytes()
    assert mesh.material.tobytes() == btr80().material.tobytes()
    assert mesh_name("btr80") == "btr80" and resolve_source("btr80") == "btr80"


def test_a_file_source_is_named_by_its_stem_and_resolves_with_its_options(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    source = "meshes/tank.stl:units=mm,up=y"
    parsed = parse_source(source)
    assert (parsed.name, parsed.units, parsed.up, parsed.forward) == ("tank", "mm", "y", "x")
    assert resolve_source(source) == f"{tmp_path / 'meshes' / 'tank.stl'}:units=mm,up=y"
    # the evaluation names a target by the stem of its source, the matcher service by the file name
    assert Path(source).stem == mesh_name(source) == "tank"
    # glTF's own conventions are its defaults; naming them changes nothing
    assert resolve_source("a.glb:up=y,forward=z") == str(tmp_path / "a.glb")


BAD_SOURCES = {  # source -> what its refusal says
    "tiger": "neither a vehicle .*leopard2.* nor a mesh file",
    "tank.stl:scale=2": "option 'scale=2'",
    "tank.stl:units=km": "units=km .*'mm'",
    "tank.obj:up=y,forward=-y": "must be different axes",
    "tank.obj:up=w": "up=w",
    "t72:units=mm": "built in code",
    "notes.txt": "neither a vehicle",
}


@pytest.mark.parametrize(("source", "message"), BAD_SOURCES.items())
def test_bad_sources_are_refused_by_name(source, message):
    with pytest.raises(InputError, match=message):
        parse_source(source)


def test_a_millimetre_file_needs_its_units(tmp_path):
    tank = vehicle("t72")
    path = tmp_path / "tank.stl"
    save_mesh(_as_file(tank, np.eye(3), scale=1000.0), path)
    with pytest.raises(InputError, match=r"9948 m long in units=m.*tank\.stl:units=mm"):
        load_mesh(path)
    _assert_same_place(load_mesh(f"{path}:units=mm"), tank)


def test_a_centimetre_sized_file_is_refused(tmp_path):
    path = tmp_path / "toy.ply"
    save_mesh(_as_file(vehicle("car"), np.eye(3), scale=0.05), path)
    with pytest.raises(InputError, match="a vehicle 0.5-30 m"):
        load_mesh(path)


def test_a_y_up_file_is_turned_upright(tmp_path):
    truck = vehicle("truck6x6")
    path = tmp_path / "truck.obj"
    save_mesh(_as_file(truck, Y_UP), path)
    _assert_same_place(load_mesh(f"{path}:up=y"), truck)


def test_a_vehicle_standing_on_its_end_is_refused_with_the_up_option(tmp_path):
    path = tmp_path / "tank.obj"
    save_mesh(_as_file(vehicle("t72"), GLTF), path)  # y up, z forward, written as OBJ
    with pytest.raises(InputError, match="taller .* than it is long.*tank.obj:up=y"):
        load_mesh(path)
    _assert_same_place(load_mesh(f"{path}:up=y,forward=z"), vehicle("t72"))


def test_a_glb_file_is_read_with_the_gltf_axes(tmp_path):
    """glTF fixes metres, +y up and +z forward: a GLB needs no option."""
    leopard = vehicle("leopard2")
    path = tmp_path / "leopard.glb"
    _write_glb(path, _as_file(leopard, GLTF))
    _assert_same_place(load_mesh(path), leopard)
    assert mesh_name(path) == "leopard"


def test_a_file_keeps_the_winding_through_a_rotation(tmp_path):
    """The axis change is a rotation: outward faces stay outward (the template builder relies on it)."""
    leopard = vehicle("leopard2")
    path = tmp_path / "leopard.obj"
    save_mesh(_as_file(leopard, GLTF), path)
    loaded = load_mesh(f"{path}:up=y,forward=z")
    a, b, c = (loaded.vertices[loaded.triangles[:, i]] for i in range(3))
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    a, b, c = (leopard.vertices[leopard.triangles[:, i]] for i in range(3))
    assert volume == pytest.approx(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0, rel=1e-5)
    assert volume > 0


def test_glb_is_not_written(tmp_path):
    with pytest.raises(InputError, match="can write .ply"):
        save_mesh(vehicle("car"), tmp_path / "car.glb")


def test_vehicle_sources_of_the_command_line(tmp_path):
    tank, truck = str(tmp_path / "tank.ply"), f"{tmp_path / 'truck.stl'}:units=mm"
    save_mesh(vehicle("m1"), tank)
    save_mesh(_as_file(vehicle("truck6x6"), np.eye(3), scale=1000.0), tmp_path / "truck.stl")
    assert vehicle_sources(None, None) == (None, ())
    assert vehicle_sources("leopard2", None, ["t72", "m113"]) == ("leopard2", ("t72", "m113"))
    assert vehicle_sources(None, tank, ["ifv"], [truck]) == (tank, ("ifv", truck))


@pytest.mark.parametrize(
    ("target", "target_mesh", "clutter", "message"),
    [
        ("leopard2", "tank.ply", [], "not both"),
        ("tank.ply", None, [], "--target tank.ply: expected a vehicle name"),
        (None, "m1", [], "--target-mesh m1: expected a mesh file"),
        ("tiger", None, [], "neither a vehicle"),
        (None, None, ["t72"], "confuser t72 is the target t72"),
        ("m109", None, ["ifv", "m109"], "confuser m109 is the target"),
        (None, "missing.ply", [], "missing.ply does not exist"),
    ],
)
def test_bad_command_line_vehicles_are_refused(target, target_mesh, clutter, message):
    with pytest.raises(InputError, match=message):
        vehicle_sources(target, target_mesh, clutter)


def test_every_vehicle_round_trips_through_a_file(tmp_path):
    for name in VEHICLES:
        path = tmp_path / f"{name}.ply"
        save_mesh(vehicle(name), path)
        _assert_same_place(load_mesh(path), vehicle(name), atol=1e-9)
