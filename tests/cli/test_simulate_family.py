"""`--target NAME` / `--clutter NAME` on `atr simulate`, `atr eval` and `atr demo`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from atr.errors import InputError
from atr.io.mesh import save_mesh
from atr.sim.vehicles import vehicle
from bus import codec
from bus.mcap_tools import iter_messages
from cli.main import build_parser, main

SMALL_CAMERA = [
    "--set",
    "sim.width_px=160",
    "--set",
    "sim.height_px=120",
    "--set",
    "sim.focal_px=250",
]


def _truth_names(path) -> list[list[str]]:
    return [
        [t["name"] for t in codec.unpack(message.data)["targets"]]
        for topic, message in iter_messages(path)
        if topic.endswith("/truth")
    ]


def test_simulate_flies_the_named_target(tmp_path):
    out = tmp_path / "leopard.mcap"
    argv = ["simulate", "--scenario", "3", "--run", "1", "--frames", "1", "--out", str(out)]
    assert main([*argv, "--target", "leopard2", "--clutter", "t72", *SMALL_CAMERA]) == 0
    assert _truth_names(out) == [["leopard2"]]


def test_simulate_flies_a_millimetre_mesh_file(tmp_path):
    save_mesh(vehicle("m113").transformed(np.diag([1e3, 1e3, 1e3, 1.0])), tmp_path / "apc.stl")
    out = tmp_path / "apc.mcap"
    argv = ["simulate", "--scenario", "3", "--run", "1", "--frames", "1", "--out", str(out)]
    assert main([*argv, "--target-mesh", f"{tmp_path / 'apc.stl'}:units=mm", *SMALL_CAMERA]) == 0
    assert _truth_names(out) == [["apc"]]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--target", "tiger"], "mesh source 'tiger' is neither a vehicle (t72, ifv"),
        (["--target", "m1", "--clutter", "m1"], "confuser m1 is the target m1"),
        (["--target-mesh", "tank.stl"], "tank.stl does not exist"),
    ],
)
def test_a_bad_vehicle_exits_1_with_one_line_and_no_traceback(tmp_path, capsys, options, message):
    out = tmp_path / "never.mcap"
    assert main(["simulate", "--frames", "1", "--out", str(out), *options]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()


def test_eval_plans_flights_of_the_named_target_and_confusers(tmp_path):
    from cli.evaluate import plan

    argv = ["eval", "--scenario", "1", "--run", "3", "--frames", "2", "--results", str(tmp_path)]
    args = build_parser("eval").parse_args([*argv, "--target", "btr80", "--clutter", "m113"])
    flights = plan(args).flights
    assert [f.target for f in flights] == ["btr80"]
    assert flights[0].clutter_meshes == ("m113",)
    with pytest.raises(InputError, match="unknown|neither a vehicle"):
        plan(build_parser("eval").parse_args([*argv, "--clutter", "tiger"]))


def test_eval_exits_1_on_an_unknown_target(tmp_path, capsys):
    assert main(["eval", "--frames", "2", "--target", "tiger", "--results", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "tiger" in err and "Traceback" not in err


def test_demo_hands_the_target_to_the_sensor_source_and_the_template_store(tmp_path):
    from cli.demo import vehicle_options

    parser = build_parser("demo")
    source_args, overrides = vehicle_options(
        parser.parse_args(["demo", "--target", "m109", "--clutter", "t72"])
    )
    assert source_args == ["--target-mesh", "m109", "--clutter-mesh", "t72"]
    assert overrides == ['pipeline.targets=["t72", "ifv", "truck6x6", "m109"]']
    # a mesh file reaches the services by its absolute path, its template through target_meshes
    save_mesh(vehicle("hmmwv"), tmp_path / "jeep.ply")
    source_args, overrides = vehicle_options(
        parser.parse_args(["demo", "--target-mesh", str(tmp_path / "jeep.ply")])
    )
    assert source_args == ["--target-mesh", str(tmp_path / "jeep.ply")]
    assert overrides == [f"pipeline.target_meshes={json.dumps([str(tmp_path / 'jeep.ply')])}"]
    # the T-72 and the default confusers need nothing
    assert vehicle_options(parser.parse_args(["demo"])) == ([], [])
