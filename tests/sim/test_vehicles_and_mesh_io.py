import numpy as np
import pytest

from atr.errors import InputError
from atr.io.mesh import load_mesh, save_mesh
from atr.sim import t72
from atr.sim.mesh import box, merge


def test_t72_proportions():
    """Published T-72 figures: hull 6.86 m, 3.59 m over the skirts, 2.19 m to the turret roof, gun
    ~2.5 m
    past the hull front (hull front at 3.43 m)."""
    m = t72()
    lo, hi = m.bounds()
    assert lo[2] == pytest.approx(0.0, abs=1e-9)
    assert hi[1] - lo[1] == pytest.approx(3.59, abs=0.05)
    hull = m.vertices[m.vertices[:, 2] < 1.0]
    assert hull[:, 0].max() == pytest.approx(3.43, abs=0.05)
    assert hi[0] - 3.43 == pytest.approx(2.5, abs=0.1)
    # turret roof (excluding cupola, machine gun and searchlight) about 2.19 m
    turret = m.vertices[(np.abs(m.vertices[:, 0] - 0.3) < 0.3) & (np.abs(m.vertices[:, 1]) < 0.2)]
    assert turret[:, 2].max() == pytest.approx(2.2, abs=0.06)


@pytest.mark.parametrize("ext", ["ply", "obj", "stl"])
def test_mesh_round_trip(tmp_path, ext):
    m = t72()
    p = tmp_path / f"t72.{ext}"
    save_mesh(m, p)
    back = load_mesh(p)
    assert back.n_triangles == m.n_triangles
    np.testing.assert_allclose(back.triangle_areas().sum(), m.triangle_areas().sum(), rtol=1e-4)
    np.testing.assert_allclose(back.bounds()[1], m.bounds()[1], atol=1e-4)


def test_loose_parts_load(tmp_path):
    parts = merge(
        [
            box((1, 1, 1), (0, 0, 0.5)),
            box((1, 1, 1), (3, 0, 0.5)),
            box((0.2, 0.2, 0.2), (0, 0, 0.5)),
        ]
    )
    p = tmp_path / "parts.ply"
    save_mesh(parts, p)
    assert load_mesh(p).n_triangles == parts.n_triangles


def test_load_errors(tmp_path):
    with pytest.raises(InputError):
        load_mesh(tmp_path / "missing.ply")
    bad = tmp_path / "x.txt"
    bad.write_text("no mesh")
    with pytest.raises(InputError):
        load_mesh(bad)
    empty = tmp_path / "empty.ply"
    empty.write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nelement face 0\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    with pytest.raises(InputError):
        load_mesh(empty)
