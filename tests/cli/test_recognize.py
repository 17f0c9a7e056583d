"""`atr recognize` end to end on files: PCL's milk carton (JSON contract) and bad inputs."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from cli.main import main

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _atr_cli import atr  # noqa: E402

SHARED = Path(__file__).resolve().parents[3] / "shared"
PCL = SHARED / "data" / "pcl"


def test_json_contract_on_pcl_milk(capsys):
    if not (PCL / "milk.pcd").is_file():
        pytest.skip(f"PCL data absent: {PCL}")
    code = main(
        [
            "recognize",
            "--model", str(PCL / "milk.pcd"),
            "--scene", str(PCL / "milk_cartoon_all_small_clorox.pcd"),
            "--descriptor", "fpfh",
            "--resolution", "auto",
            "--max-keypoints", "6000",
            "--viewpoint", "0", "0", "0",
            "--json",
        ]
    )  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"detections", "stage_times_ms"}
    det = out["detections"][0]
    assert set(det) == {"target", "descriptor", "T_world_target", "score", "overlap", "inliers"}
    assert det["target"] == "milk" and det["descriptor"] == "fpfh"
    T = np.array(det["T_world_target"])
    assert T.shape == (4, 4) and np.linalg.norm(T[:3, 3]) < 0.01


def test_text_output_and_xyz_mesh_inputs(tmp_path, capsys):
    import open3d as o3d

    from atr.recognition import synthetic as syn

    v, f = syn.car_like()
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(f))
    o3d.io.write_triangle_mesh(str(tmp_path / "car.ply"), mesh)
    scene = syn.aerial_scene([((v, f), syn.pose(1.0, 2.0, 0.3))], seed=0, extent_m=10, n_clutter=0)
    np.savetxt(tmp_path / "scene.xyz", scene)
    code = main(
        ["recognize", "--model", str(tmp_path / "car.ply"), "--scene", str(tmp_path / "scene.xyz"),
         "--descriptor", "fpfh"]
    )  # fmt: skip
    text = capsys.readouterr().out
    assert code == 0
    assert "stage times (ms)" in text and "resolution 0.3 m" in text


def test_bad_files_exit_1(tmp_path, capsys):
    (tmp_path / "bad.xyz").write_text("1 2\n3 4\n")
    assert (
        main(
            [
                "recognize",
                "--model",
                str(tmp_path / "none.pcd"),
                "--scene",
                str(tmp_path / "bad.xyz"),
            ]
        )
        == 1
    )
    assert "no such file" in capsys.readouterr().err
    (tmp_path / "m.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    assert (
        main(
            ["recognize", "--model", str(tmp_path / "m.xyz"), "--scene", str(tmp_path / "bad.xyz")]
        )
        == 1
    )
    assert "columns" in capsys.readouterr().err
    assert main(["recognize", "--model", str(tmp_path / "m.xyz"), "--scene", str(tmp_path / "m.xyz"),
                 "--resolution", "abc"]) == 1  # fmt: skip


def test_a_scene_read_only_in_part_a_directory_or_an_absurd_value_is_refused(tmp_path):
    rng = np.random.default_rng(0)
    np.savetxt(tmp_path / "model.xyz", rng.uniform(0, 3, (300, 3)))
    header = "ply\nformat ascii 1.0\nelement vertex 3\n" + "".join(
        f"property float {axis}\n" for axis in "xyz"
    )
    (tmp_path / "inf.ply").write_text(header + "end_header\n0 0 0\n1 inf 0\n0 1 0\n")
    (tmp_path / "random.ply").write_bytes(rng.bytes(2048))
    (tmp_path / "header.ply").write_text(header.replace("float y", "flaot y") + "end_header\n")
    (tmp_path / "folder").mkdir()
    far = rng.uniform(0, 3, (300, 3))
    far[7, 2] = 1e30
    np.savetxt(tmp_path / "far.xyz", far)
    cases = {
        "inf.ply": "positions must be finite",
        "random.ply": "not a PLY file",
        "header.ply": "'property flaot y' is malformed",
        "folder": "folder is a directory",
        "far.xyz": "point 7 has z = 1e+30",
    }
    for scene, reason in cases.items():
        done = atr("recognize", "--model", "model.xyz", "--scene", scene, cwd=tmp_path)
        assert done.returncode == 1, (scene, done.stdout, done.stderr)
        assert "Traceback" not in done.stderr
        assert scene in done.stderr and reason in done.stderr, done.stderr
    done = atr("recognize", "--model", "model.xyz", "--scene", "model.xyz", "--viewpoint",
               "0", "1e30", "0", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 1 and "--viewpoint" in done.stderr and "Traceback" not in done.stderr
