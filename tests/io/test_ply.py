"""The strict PLY reader: whatever Open3D writes is read identically; whatever it would read only in part is
refused with the file and the reason."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

from atr.errors import InputError
from atr.io.geometry import load_geometry
from atr.io.ply import read_ply

_HEADER = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"


def _mesh() -> o3d.geometry.TriangleMesh:
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float) * 0.37
    triangles = np.array([[0, 1, 2], [0, 1, 3], [1, 2, 4], [0, 2, 3]])
    return o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(triangles)
    )


@pytest.mark.parametrize("ascii_", [False, True], ids=["binary", "ascii"])
def test_meshes_and_clouds_open3d_writes_are_read_as_open3d_reads_them(
    tmp_path: Path, ascii_: bool
) -> None:
    mesh_path = tmp_path / "mesh.ply"
    o3d.io.write_triangle_mesh(str(mesh_path), _mesh(), write_ascii=ascii_)
    ply = read_ply(mesh_path)
    reference = o3d.io.read_triangle_mesh(str(mesh_path))
    assert np.allclose(ply.points, np.asarray(reference.vertices))
    assert np.array_equal(ply.triangles, np.asarray(reference.triangles))

    points = np.random.default_rng(0).normal(size=(50, 3))
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.normals = o3d.utility.Vector3dVector(np.ones((50, 3)))  # more properties than x y z
    cloud_path = tmp_path / "cloud.ply"
    o3d.io.write_point_cloud(str(cloud_path), cloud, write_ascii=ascii_)
    geometry = load_geometry(cloud_path)
    assert not geometry.is_mesh and np.allclose(geometry.points, points, atol=1e-5)


def test_polygons_are_fanned_into_triangles(tmp_path: Path) -> None:
    path = tmp_path / "quad.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"
    )
    assert read_ply(path).triangles.tolist() == [[0, 1, 2], [0, 2, 3]]


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (_HEADER + "end_header\n0 0 0\n1 inf 0\n0 1 0\n", "vertex 1 is [1.0, inf, 0.0]"),
        (_HEADER + "end_header\n0 0 0\n1 nan 0\n0 1 0\n", "must be finite"),
        (_HEADER + "end_header\n0 0 0\n1 x 0\n0 1 0\n", "'x', which is not a number"),
        (_HEADER + "end_header\n0 0 0\n1 0 0\n", "ends inside element 'vertex'"),
        (_HEADER.replace("float y", "floot y") + "end_header\n", "line 5 'property floot y'"),
        (_HEADER.replace("ascii", "text"), "no 'end_header'"),
        (_HEADER.replace("ascii", "text") + "end_header\n", "format 'text 1.0'"),
        ("solid cube\nfacet normal 0 0 1\n", "not a PLY file"),
        (
            _HEADER + "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
            "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
            "vertex 7; expected an index in 0..2",
        ),
    ],
    ids=["inf", "nan", "word", "short", "bad-type", "no-end", "bad-format", "not-ply", "bad-face"],
)
def test_a_file_that_cannot_be_read_whole_is_refused_naming_it(
    tmp_path: Path, content: str, reason: str
) -> None:
    path = tmp_path / "bad.ply"
    path.write_text(content)
    with pytest.raises(InputError, match="bad.ply") as error:
        load_geometry(path)
    assert reason in str(error.value)


def test_a_truncated_binary_file_and_random_bytes_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "mesh.ply"
    o3d.io.write_triangle_mesh(str(path), _mesh(), write_ascii=False)
    path.write_bytes(path.read_bytes()[:-7])
    with pytest.raises(InputError, match="ends inside element 'face'"):
        read_ply(path)
    path.write_bytes(np.random.default_rng(1).bytes(4096))
    with pytest.raises(InputError, match="not a PLY file"):
        read_ply(path)


def test_absurd_coordinates_and_directories_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "far.xyz"
    np.savetxt(path, [[0, 0, 0], [1, 2, 3], [0, -1e30, 0]])
    with pytest.raises(InputError, match=r"point 2 has y = -1e\+30; expected a finite coordinate"):
        load_geometry(path)
    (tmp_path / "folder.ply").mkdir()
    with pytest.raises(InputError, match="folder.ply is a directory"):
        load_geometry(tmp_path / "folder.ply")
