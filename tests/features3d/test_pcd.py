"""PCD reader: ascii, binary, binary_compressed (LZF), against Open3D's reader and hand-made files."""

import numpy as np
import open3d as o3d
import pytest

from atr.errors import InputError
from atr.io.pcd import lzf_decompress, read_pcd, read_pcd_xyz

from .conftest import DATA, SHARED

HEADER = (
    "VERSION 0.7\nFIELDS x y z label\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
    "WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {kind}\n"
)


def test_ascii_matches_open3d_and_keeps_all_fields(bun0_fields):
    assert set(bun0_fields) == {"x", "y", "z", "normal_x", "normal_y", "normal_z", "curvature"}
    assert bun0_fields["x"].dtype == np.float32 and bun0_fields["x"].shape == (397,)
    ref = np.asarray(o3d.io.read_point_cloud(str(DATA / "bun0.pcd")).points)
    np.testing.assert_allclose(read_pcd_xyz(DATA / "bun0.pcd"), ref, atol=1e-7)


def test_binary_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(50, 3)).astype(np.float32)
    label = rng.integers(0, 2**32 - 1, size=50, dtype=np.uint32)
    rec = np.zeros(50, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("label", "<u4")])
    rec["x"], rec["y"], rec["z"], rec["label"] = xyz[:, 0], xyz[:, 1], xyz[:, 2], label
    path = tmp_path / "c.pcd"
    path.write_bytes(HEADER.format(n=50, kind="binary").encode() + rec.tobytes())
    out = read_pcd(path)
    np.testing.assert_array_equal(out["label"], label)
    np.testing.assert_array_equal(np.stack([out["x"], out["y"], out["z"]], 1), xyz)


def test_lzf_literal_and_overlapping_back_reference():
    # LZF format: ctrl < 32 = literal run of ctrl+1 bytes; else length (ctrl>>5, 7 = extended by the next byte)
    # + 2 bytes copied from offset ((ctrl & 31) << 8 | next) + 1 back. "ab" then copy 9 from 2 back.
    stream = bytes([1, ord("a"), ord("b"), 0xE0, 0, 1])
    assert lzf_decompress(stream, 11) == b"ababababab" + b"a"
    with pytest.raises(InputError):
        lzf_decompress(bytes([0xE0, 0, 40]), 9)  # reference before the start


@pytest.mark.skipif(
    not (SHARED / "data" / "pcl" / "milk.pcd").exists(), reason="../shared/data/pcl not present"
)
@pytest.mark.parametrize("name", ["milk.pcd", "milk_cartoon_all_small_clorox.pcd"])
def test_binary_compressed_matches_open3d(name):
    path = SHARED / "data" / "pcl" / name
    xyz = read_pcd_xyz(path)
    finite = np.isfinite(xyz).all(axis=1)
    ref = np.asarray(o3d.io.read_point_cloud(str(path), remove_nan_points=True).points)
    np.testing.assert_array_equal(xyz[finite], ref)
    if name.startswith("milk_cartoon"):
        assert xyz.shape == (640 * 480, 3) and finite.sum() == 241_407  # oracle notes §0


def test_truncated_file_is_an_input_error(tmp_path):
    path = tmp_path / "t.pcd"
    path.write_bytes(HEADER.format(n=10, kind="binary").encode() + b"\0" * 20)
    with pytest.raises(InputError, match="expected"):
        read_pcd(path)
    with pytest.raises(InputError):
        read_pcd(tmp_path / "missing.pcd")
