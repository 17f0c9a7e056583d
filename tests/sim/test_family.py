"""The vehicle family: closed meshes of published sizes, distinct names and shapes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from atr.errors import InputError
from atr.sim.mesh import Mesh
from atr.sim.vehicles import FAMILY, VEHICLES, vehicle

# The models follow the published overall length (gun forward) and width closely; their height may carry
# roof fittings (machine guns, sights) that a sheet's "height" leaves out.
LENGTH_WIDTH_TOLERANCE = 0.05  # relative
HEIGHT_TOLERANCE = 0.10  # relative
# Two tanks of one generation are alike (the T-72 and the M1A1 differ by < 0.13 m in every overall
# dimension): the shapes must still differ, by this much on average, metres.
MIN_SURFACE_DISTANCE_M = 0.1
# The four vehicles the committed evaluation and recordings were made with keep their prisms wound
# inward (atr.sim.mesh.extrude_profile_inward), so that those stay byte-identical.
WOUND_INWARD = {"t72", "ifv", "truck6x6", "car"}


def _directed_edges(mesh: Mesh) -> np.ndarray:
    t = mesh.triangles.astype(np.int64)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return e[:, 0] * (1 << 32) + e[:, 1]


def _component_volumes(mesh: Mesh) -> np.ndarray:
    """Signed volume of each connected part, m³ (positive when its faces point outwards)."""
    t = mesh.triangles
    n = len(mesh.vertices)
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    a, b, c = (mesh.vertices[t[:, i]] for i in range(3))
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    return np.bincount(label[t[:, 0]], weights=volume, minlength=count)


def test_at_least_eight_vehicles_beside_the_t72_with_unique_names():
    names = [spec.name for spec in FAMILY]
    assert len(set(names)) == len(names)
    assert names[0] == "t72" and len(names) >= 9
    assert list(VEHICLES) == names
    kinds = {spec.kind for spec in FAMILY}
    assert len(kinds) >= 7  # tanks, tracked and wheeled carriers, a howitzer, trucks, cars


@pytest.mark.parametrize("spec", FAMILY, ids=lambda s: s.name)
def test_every_vehicle_is_a_closed_mesh(spec):
    """Every edge is shared by exactly two triangles that run along it in opposite directions."""
    mesh = spec.build()
    assert mesh.n_triangles > 100 and np.all(mesh.triangle_areas() > 1e-9)
    edges = _directed_edges(mesh)
    reverse = (edges % (1 << 32)) * (1 << 32) + edges // (1 << 32)
    assert len(np.unique(edges)) == len(edges), "an edge is used twice in the same direction"
    assert np.isin(reverse, edges).all(), "an edge has a triangle on one side only"


@pytest.mark.parametrize(
    "spec",
    [
        pytest.param(
            s,
            marks=pytest.mark.xfail(strict=True, reason="committed model, prisms wound inward"),
        )
        if s.name in WOUND_INWARD
        else s
        for s in FAMILY
    ],
    ids=lambda s: s.name,
)
def test_every_part_faces_outwards(spec):
    """The template builder orients normals by the winding: each closed part encloses a positive volume."""
    assert _component_volumes(spec.build()).min() > 0.0


@pytest.mark.parametrize("spec", FAMILY, ids=lambda s: s.name)
def test_size_is_the_published_one(spec):
    lo, hi = spec.build().bounds()
    length, width, height = hi - lo
    published_l, published_w, published_h = spec.size_m
    assert length == pytest.approx(published_l, rel=LENGTH_WIDTH_TOLERANCE)
    assert width == pytest.approx(published_w, rel=LENGTH_WIDTH_TOLERANCE)
    assert height == pytest.approx(published_h, rel=HEIGHT_TOLERANCE)
    # vehicle frame: standing on the ground, symmetric about the x axis
    assert lo[2] == pytest.approx(0.0, abs=1e-9)
    assert hi[1] + lo[1] == pytest.approx(0.0, abs=0.05)
    assert spec.source


def test_no_two_vehicles_have_the_same_shape():
    """A point of one vehicle's surface lies on average at least MIN_SURFACE_DISTANCE_M from the other's
    (both in their vehicle frames; symmetric mean of the closest-point distances)."""
    rng = np.random.default_rng(0)
    samples = {spec.name: spec.build().sample_surface(4000, rng) for spec in FAMILY}
    for a, b in itertools.combinations(samples, 2):
        a_to_b = cKDTree(samples[b]).query(samples[a])[0].mean()
        b_to_a = cKDTree(samples[a]).query(samples[b])[0].mean()
        assert 0.5 * (a_to_b + b_to_a) > MIN_SURFACE_DISTANCE_M, (a, b)


def test_a_vehicle_is_built_the_same_every_time():
    for name in VEHICLES:
        one, two = vehicle(name), vehicle(name)
        assert one.vertices.tobytes() == two.vertices.tobytes()
        assert one.triangles.tobytes() == two.triangles.tobytes()
        assert one.material.tobytes() == two.material.tobytes()


def test_an_unknown_vehicle_is_refused_with_the_known_names():
    with pytest.raises(InputError, match="unknown vehicle 'tiger'") as error:
        vehicle("tiger")
    for name in VEHICLES:
        assert name in str(error.value)
