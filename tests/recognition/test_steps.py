"""Unit tests of the matcher's steps: each pins a property that fails if the step breaks."""

import math
from dataclasses import replace

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from atr.errors import ConfigError, InputError
from atr.recognition import (
    Correspondences,
    Hypothesis,
    PointSet,
    RansacSettings,
    RecognitionConfig,
    Template,
    VerifySettings,
    descriptor_sq_distances,
    drop_repeated_hypotheses,
    filter_smooth_surfaces,
    group_geometrically_consistent,
    height_above_ground,
    knndr_from_distances,
    lowest_per_cell,
    match_knndr,
    normal_spread,
    ransac_per_group,
    rigid_transform,
    terrain_height_at,
    uniform_subsample,
    upright_rigid_transform,
    verify_with_icp,
)
from atr.recognition._backend import estimate_normals


def _verify(model, scene, T, gate_m, overlap_m, iterations, scene_sigma_m=None, **kw):
    """``verify_with_icp`` with its settings given as arguments."""
    settings = VerifySettings(gate_m, overlap_m, iterations, **kw)
    return verify_with_icp(PointSet(model), PointSet(scene, scene_sigma_m), T, settings)


def _random_pose(rng):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(rng.normal(size=4), scalar_first=True).as_matrix()
    T[:3, 3] = rng.uniform(-5, 5, 3)
    return T


def test_uniform_subsample_keeps_point_nearest_each_voxel_centre():
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1, 1, (3000, 3))
    leaf = 0.25
    idx = uniform_subsample(pts, leaf)
    cells = np.floor(pts / leaf).astype(int)
    # one kept point per occupied voxel
    assert len(idx) == len({tuple(c) for c in cells})
    assert len({tuple(c) for c in cells[idx]}) == len(idx)
    # brute force: the kept point is the one closest to its voxel centre
    d = np.linalg.norm(pts - (cells + 0.5) * leaf, axis=1)
    for i in idx[:200]:
        same = np.all(cells == cells[i], axis=1)
        assert d[i] == d[same].min()


def test_uniform_subsample_rejects_bad_leaf_and_handles_empty():
    with pytest.raises(InputError):
        uniform_subsample(np.zeros((4, 3)), 0.0)
    assert len(uniform_subsample(np.zeros((0, 3)), 0.3)) == 0


def test_smooth_surface_filter_drops_plane_keeps_edges():
    g = np.arange(0, 6, 0.3)
    xx, yy = np.meshgrid(g, g)
    plane = np.c_[xx.ravel(), yy.ravel(), np.zeros(xx.size)]
    # a box sitting on the plane: its edges and corners are not smooth
    box = []
    for x in np.arange(2.1, 3.91, 0.3):
        for z in np.arange(0.3, 1.81, 0.3):
            box += [(x, 2.1, z), (x, 3.9, z), (2.1, x, z), (3.9, x, z)]
    pts = np.unique(np.round(np.r_[plane, np.array(box)], 6), axis=0)
    normals = estimate_normals(pts, 6, None)
    keep = filter_smooth_surfaces(pts, normals, 6, math.radians(10))
    far_plane = (pts[:, 2] == 0) & (np.min(np.abs(pts[:, :2] - 3.0), axis=1) > 1.5)
    assert not keep[far_plane].any()
    corner = np.all(np.isclose(pts, [2.1, 2.1, 1.8]), axis=1)
    assert keep[corner].all()


def test_knndr_matches_identical_descriptors_and_applies_ratio():
    rng = np.random.default_rng(2)
    model = rng.normal(size=(50, 16))
    scene = model[[3, 7, 11]] + 1e-3 * rng.normal(size=(3, 16))
    corr = match_knndr(scene, model, k=10, ratio=0.8)
    best = {}
    for s, m in zip(corr.scene, corr.model, strict=True):  # sorted by distance: first is nearest
        best.setdefault(int(s), int(m))
    assert best == {0: 3, 1: 7, 2: 11}
    assert np.all(np.diff(corr.distance) >= 0)
    # a scene descriptor equidistant from everything has no distinctive match
    flat = np.zeros((1, 16))
    model_ring = np.eye(16)[:12]
    assert len(match_knndr(flat, model_ring, k=10, ratio=0.8)) == 0


def test_knndr_ignores_nan_rows_and_checks_shapes():
    model = np.eye(4)
    scene = np.array([[np.nan] * 4, [1.0, 0, 0, 0]])
    corr = match_knndr(scene, model, k=3, ratio=0.9)
    assert set(corr.scene.tolist()) == {1}
    with pytest.raises(InputError):
        match_knndr(np.zeros((2, 3)), np.zeros((2, 4)), k=2, ratio=0.8)


def _rigid_case(seed, n_true=40, n_out=60):
    rng = np.random.default_rng(seed)
    model = rng.uniform(-3, 3, (100, 3))
    T = _random_pose(rng)
    scene = model @ T[:3, :3].T + T[:3, 3]
    true_m = np.arange(n_true)
    out_m = rng.integers(0, 100, n_out)
    out_s = rng.integers(0, 100, n_out)
    corr = Correspondences(
        scene=np.r_[true_m, out_s].astype(np.int64),
        model=np.r_[true_m, out_m].astype(np.int64),
        distance=np.r_[np.linspace(0, 1, n_true), np.linspace(0.5, 2, n_out)],
    )
    return model, scene, T, corr, n_true


def test_geometric_consistency_groups_the_true_correspondences():
    model, scene, _, corr, n_true = _rigid_case(3)
    groups = group_geometrically_consistent(scene, model, corr, 0.05, 5)
    assert groups
    g0 = set(groups[0].tolist())
    assert set(range(n_true)) <= g0
    assert len(g0) < n_true + 5  # outliers are rarely distance-consistent


def test_ransac_recovers_pose_and_is_deterministic():
    model, scene, T, corr, _ = _rigid_case(4)
    group = np.arange(len(corr))
    settings = RansacSettings(1000, 0.05)
    h1 = ransac_per_group(scene, model, corr, group, settings, np.random.default_rng(9))
    h2 = ransac_per_group(scene, model, corr, group, settings, np.random.default_rng(9))
    assert h1 is not None and h2 is not None
    np.testing.assert_allclose(h1.T_scene_model, T, atol=1e-9)
    assert np.array_equal(h1.T_scene_model, h2.T_scene_model)
    assert h1.inliers >= 40


def _upright_pose(yaw_deg: float, t: list[float]) -> np.ndarray:
    c, s_ = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    T = np.eye(4)
    T[:3, :3] = [[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = t
    return T


def test_repeated_hypotheses_of_a_view_are_verified_once():
    def hyp(yaw_deg: float, t: list[float], inliers: int) -> Hypothesis:
        return Hypothesis(_upright_pose(yaw_deg, t), inliers, inliers)

    first = (0, hyp(30.0, [10.0, 5.0, 0.0], 40))
    hyps = [
        first,
        (0, hyp(31.0, [10.1, 5.0, 0.0], 30)),  # the same pose again: dropped
        (1, hyp(30.0, [10.0, 5.0, 0.0], 30)),  # another view of the template: kept
        (0, hyp(33.0, [10.0, 5.0, 0.0], 20)),  # turned 3 deg: kept
        (0, hyp(30.0, [10.0, 5.2, 0.0], 20)),  # 0.2 m away: kept
    ]
    kept = drop_repeated_hypotheses(hyps, 0.15, math.radians(2.0))
    assert kept == [hyps[0], hyps[2], hyps[3], hyps[4]]
    # the rotation test sees any axis, not only the heading
    tilted = _upright_pose(30.0, [10.0, 5.0, 0.0])
    c, s_ = math.cos(math.radians(3.0)), math.sin(math.radians(3.0))
    tilted[:3, :3] = tilted[:3, :3] @ np.array([[1.0, 0.0, 0.0], [0.0, c, -s_], [0.0, s_, c]])
    assert len(drop_repeated_hypotheses([first, (0, Hypothesis(tilted, 9, 9))], 0.15, 0.035)) == 2


def test_upright_ransac_keeps_a_side_view_standing():
    """A vehicle's side seen at 0 deg: keypoints on a near-vertical plane, 3 cm noise, a third outliers.
    The heading-only fit recovers the pose and cannot tilt it."""
    rng = np.random.default_rng(11)
    n_true, n_out = 60, 30
    side = np.c_[
        rng.uniform(-3.5, 3.5, n_true), rng.normal(0.0, 0.05, n_true), rng.uniform(0.4, 2.2, n_true)
    ]
    T = _upright_pose(40.0, [12.0, -5.0, 0.3])
    scene_true = side @ T[:3, :3].T + T[:3, 3] + rng.normal(0.0, 0.03, side.shape)
    model = np.r_[side, rng.uniform(-3.5, 3.5, (n_out, 3))]
    scene = np.r_[scene_true, rng.uniform(-3.5, 3.5, (n_out, 3)) + T[:3, 3]]
    corr = Correspondences(
        scene=np.arange(n_true + n_out),
        model=np.arange(n_true + n_out),
        distance=np.zeros(n_true + n_out),
    )
    group = np.arange(n_true + n_out)
    settings = RansacSettings(1000, 0.1)
    up = ransac_per_group(
        scene, model, corr, group, replace(settings, upright=True), np.random.default_rng(2)
    )
    rigid = ransac_per_group(scene, model, corr, group, settings, np.random.default_rng(2))
    assert up is not None and rigid is not None
    assert np.array_equal(up.T_scene_model[2, :3], [0.0, 0.0, 1.0])  # standing, exactly
    yaw = math.degrees(math.atan2(up.T_scene_model[1, 0], up.T_scene_model[0, 0]))
    assert abs(yaw - 40.0) < 1.0
    np.testing.assert_allclose(up.T_scene_model[:3, 3], T[:3, 3], atol=0.05)
    assert up.inliers >= 0.9 * n_true
    # the rigid fit of the same group leans (0.2 deg here; tens of degrees on sparse SfM side views)
    assert not np.array_equal(rigid.T_scene_model[2, :3], [0.0, 0.0, 1.0])


def test_upright_rigid_transform_is_exact_on_a_turned_copy():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(15, 3))
    T = _upright_pose(-125.0, [3.0, 4.0, -1.0])
    np.testing.assert_allclose(
        upright_rigid_transform(a, a @ T[:3, :3].T + T[:3, 3]), T, atol=1e-12
    )


def test_rigid_transform_identities():
    rng = np.random.default_rng(5)
    T = _random_pose(rng)
    a = rng.normal(size=(20, 3))
    b = a @ T[:3, :3].T + T[:3, 3]
    est = rigid_transform(a, b)
    np.testing.assert_allclose(est @ np.linalg.inv(est), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(est, T, atol=1e-9)
    assert np.isclose(np.linalg.det(est[:3, :3]), 1.0)


def test_config_validates():
    with pytest.raises(ConfigError):
        RecognitionConfig(resolution_m=0.0)
    with pytest.raises(ConfigError):
        RecognitionConfig(descriptor="sift")
    with pytest.raises(ConfigError):
        RecognitionConfig(knndr_ratio=1.5)
    cfg = RecognitionConfig()
    assert cfg.resolution_m == 0.3 and cfg.knndr_k == 10
    assert cfg.ransac_iterations == 1000
    assert math.isclose(cfg.support_radius_m, cfg.k_support_radius * 0.3)


def _random_template(rng, radius_m, params):
    """An FPFH template of 30 random points and 20 random keypoints."""
    return Template(
        target="t72",
        descriptor="fpfh",
        points_m=rng.normal(size=(30, 3)).astype(np.float32),
        normals=rng.normal(size=(30, 3)).astype(np.float32),
        keypoints_m=rng.normal(size=(20, 3)).astype(np.float32),
        descriptors=rng.normal(size=(20, 33)).astype(np.float32),
        radius_m=radius_m,
        params=params,
    )


def test_template_round_trips_through_dict_and_msgpack():
    msgpack = pytest.importorskip("msgpack")
    t = _random_template(
        np.random.default_rng(6), 1.5, {"resolution_m": 0.3, "template_azimuths_deg": [0.0, 90.0]}
    )

    def enc(o):
        if isinstance(o, np.ndarray):
            return msgpack.ExtType(1, msgpack.packb([o.dtype.str, list(o.shape), o.tobytes()]))
        raise TypeError(type(o))

    def dec(code, data):
        dt, shape, raw = msgpack.unpackb(data)
        return np.frombuffer(raw, dtype=dt).reshape(shape)

    back = Template.from_dict(
        msgpack.unpackb(msgpack.packb(t.to_dict(), default=enc), ext_hook=dec)
    )
    for f in ("points_m", "normals", "keypoints_m", "descriptors"):
        assert np.array_equal(getattr(back, f), getattr(t, f))
    assert (back.target, back.descriptor, back.radius_m, back.params) == (
        t.target,
        t.descriptor,
        t.radius_m,
        t.params,
    )
    bad = t.to_dict()
    bad["descriptors"] = bad["descriptors"][:5]
    with pytest.raises(InputError):
        Template.from_dict(bad)


def test_height_above_ground_on_terrain_with_vehicle_and_outliers():
    rng = np.random.default_rng(11)
    xy = rng.uniform(-20, 20, (6000, 2))
    ground_z = 0.02 * xy[:, 0] + 5.0  # gentle slope, offset
    pts = np.c_[xy, ground_z + rng.normal(0, 0.03, len(xy))]
    # a 7 x 3.6 x 2.2 m box on the ground: its roof must stand 2.2 m up, not count as ground
    bx = rng.uniform([-3.5, -1.8], [3.5, 1.8], (800, 2))
    roof = np.c_[bx, 0.02 * bx[:, 0] + 5.0 + 2.2]
    below = np.c_[rng.uniform(-20, 20, (20, 2)), np.full(20, 3.0)]  # reconstruction outliers
    cloud = np.r_[pts, roof, below]
    h = height_above_ground(cloud, 1.5, 4.5, 20.0)
    # the lowest point of a cell lies ~1-2 sigma under the mean ground: well inside the 0.3 m ground cut
    assert np.median(np.abs(h[: len(pts)])) < 0.15
    np.testing.assert_allclose(np.median(h[len(pts) : len(pts) + len(roof)]), 2.2, atol=0.15)


def test_ground_of_a_sparse_cloud_spanning_tens_of_km_costs_what_its_points_cost():
    """40 points spread over 30 km: the former dense grid held 4e8 cells (3.2 GB) for them."""
    import tracemalloc

    rng = np.random.default_rng(5)
    pts = np.c_[rng.uniform(-15_000, 15_000, (40, 2)), rng.normal(0, 1, 40)]
    pts[:2, :2] = [[-15_000, -15_000], [15_000, 15_000]]
    tracemalloc.start()
    try:
        h = height_above_ground(pts, 1.5, 4.5, 20.0)
        cells = lowest_per_cell(pts, 1.5)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000, f"{peak} bytes for 40 points"
    assert len(cells[1]) == 40  # one cell per isolated point, nothing else materialised
    # each point is alone in its window: the window's only value is its own cell's lowest point
    np.testing.assert_array_equal(h, np.zeros(40))


def test_ground_refuses_a_cloud_beyond_the_int64_cell_keys():
    pts = np.array([[0.0, 0.0, 0.0], [1e30, 0.0, 0.0]])
    with pytest.raises(InputError, match="ground grid"):
        height_above_ground(pts, 1.5, 4.5, 20.0)


def test_terrain_under_a_roof_is_the_ground_around_the_building():
    rng = np.random.default_rng(13)
    xy = rng.uniform(-30, 30, (20000, 2))
    ground = 0.05 * xy[:, 0]  # a 5 % slope
    on_roof = np.all(np.abs(xy) < 8.0, axis=1)  # a 16 x 16 m building, 6 m high
    pts = np.c_[xy, np.where(on_roof, ground + 6.0, ground)]
    cells = lowest_per_cell(pts, 1.5)
    query = np.array([[0.0, 0.0], [20.0, 0.0], [500.0, 500.0]])
    local = terrain_height_at(*cells, query, 4.5, 20.0)
    wide = terrain_height_at(*cells, query, 18.0, 20.0)
    assert local[0] > 5.0  # a window smaller than the roof sees only the roof
    # the wide window sees the terrain; on the slope its 20th percentile lies downhill, by 0.6 x the
    # half-window (a square window) plus up to a cell
    downhill_m = (0.6 * 18.0 + 1.5) * 0.05
    assert -downhill_m < wide[0] < 0.2
    assert -downhill_m < wide[1] - 1.0 < 0.2
    assert np.isnan(wide[2])  # no cell in the window


def test_knndr_from_distances_equals_match_knndr():
    rng = np.random.default_rng(12)
    s, m = rng.normal(size=(40, 33)), rng.normal(size=(70, 33))
    a = match_knndr(s, m, 10, 0.9)
    b = knndr_from_distances(descriptor_sq_distances(s, m), 10, 0.9)
    assert np.array_equal(a.scene, b.scene) and np.array_equal(a.model, b.model)
    d = np.linalg.norm(s[a.scene] - m[a.model], axis=1)
    np.testing.assert_allclose(a.distance, d, rtol=1e-4)


def test_upright_hough_groups_true_correspondences_and_uses_heights(hough):
    rng = np.random.default_rng(13)
    model = np.c_[rng.uniform(-3.5, 3.5, (200, 2)), rng.uniform(0.3, 2.2, 200)]
    yaw = 1.1
    c, s_ = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
    t = np.array([40.0, -12.0, 3.0])  # ground at z = 3
    scene = model @ R.T + t
    heights = scene[:, 2] - 3.0
    n_true, n_out = 30, 600
    corr = Correspondences(
        scene=np.r_[np.arange(n_true), rng.integers(0, 200, n_out)].astype(np.int64),
        model=np.r_[np.arange(n_true), rng.integers(0, 200, n_out)].astype(np.int64),
        distance=np.zeros(n_true + n_out),
    )
    settings = {
        "cell_m": 0.9,
        "yaw_bin_rad": math.radians(10),
        "height_tol_m": 0.45,
        "min_size": 5,
        "max_groups": 5,
    }
    groups = hough(scene, heights, model, corr, **settings)
    assert groups
    assert set(range(n_true)) <= set(groups[0].tolist())
    assert (
        len(groups[0]) < 3 * n_true
    )  # 600 random outliers: the peak is mostly true correspondences
    # the same correspondences with the scene lifted 1 m off the ground are height-inconsistent
    none = hough(scene, heights + 1.0, model, corr, **settings)
    assert all(len(set(range(n_true)) & set(g.tolist())) < 5 for g in none)


def test_multi_view_template_slices_and_validation():
    t = _random_template(
        np.random.default_rng(14),
        3.0,
        {"resolution_m": 0.3, "view_points": [10, 20], "view_keypoints": [5, 15]},
    )
    back = Template.from_dict(t.to_dict())
    assert back.view_slices() == [(slice(0, 10), slice(0, 5)), (slice(10, 30), slice(5, 20))]
    bad = t.to_dict()
    bad["params"] = {"view_points": [10, 21], "view_keypoints": [5, 15]}
    with pytest.raises(InputError):
        Template.from_dict(bad)


def _box_surface(spacing_m: float, offset_m: float = 0.0) -> np.ndarray:
    """Top and two sides of a 6 x 3 x 2 m box, sampled on a grid of the given spacing."""
    u = np.arange(offset_m, 6.0, spacing_m)
    v = np.arange(offset_m, 3.0, spacing_m)
    w = np.arange(offset_m, 2.0, spacing_m)
    top = np.stack(np.meshgrid(u, v, [2.0], indexing="ij"), -1).reshape(-1, 3)
    side = np.stack(np.meshgrid(u, [0.0], w, indexing="ij"), -1).reshape(-1, 3)
    end = np.stack(np.meshgrid([0.0], v, w, indexing="ij"), -1).reshape(-1, 3)
    return np.concatenate([top, side, end])


def test_verify_overlap_follows_a_sparse_scene_spacing_but_not_a_dense_one():
    model = _box_surface(0.3)
    # a far target in a two-view cloud: the same surface, sampled every 0.9 m
    sparse = _box_surface(0.9, offset_m=0.45)
    v = _verify(model, sparse, np.eye(4), 0.6, 0.3, 0)
    assert v.overlap >= 0.9
    # at the fixed 0.3 m distance a 0.9 m grid explains under half of the model
    hit = np.isfinite(cKDTree(sparse).query(model, distance_upper_bound=0.3)[0])
    assert hit.mean() < 0.5
    # a dense scene keeps the configured distance: a copy 0.4 m off every face does not overlap
    dense_off = _box_surface(0.3) + 0.4
    v_dense = _verify(model, dense_off, np.eye(4), 0.6, 0.3, 0)
    assert v_dense.overlap < 0.5
    # clutter keeps the fixed distance: a pole of sparse points 1 m inside the box is unexplained
    pole = np.stack([np.full(3, 3.0), np.full(3, 1.5), [0.9, 1.2, 1.5]], -1)
    v_pole = _verify(model, np.concatenate([sparse, pole]), np.eye(4), 0.6, 0.3, 0)
    assert v_pole.clutter > v.clutter


def _box_on_wide_ground(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A 0.3 m box surface and a scene of it, noisy, at (20, 10, 0) on a wide ground it touches."""
    model = _box_surface(0.3)
    rng = np.random.default_rng(seed)
    target = model + np.array([20.0, 10.0, 0.0]) + rng.normal(0.0, 0.03, model.shape)
    ground = np.stack(np.meshgrid(np.arange(-20, 60, 0.3), np.arange(-30, 50, 0.3), [0.0]), -1)
    return model, np.concatenate([ground.reshape(-1, 3), target])


def test_verify_on_the_hypothesis_neighbourhood_equals_verify_on_the_whole_scene():
    # the box half a metre off its hypothesis
    model, scene = _box_on_wide_ground(3)
    T = np.eye(4)
    T[:3, 3] = [20.4, 9.7, 0.1]
    whole = _verify(model, scene, T, 0.6, 0.3, 30)
    near = _verify(model, scene, T, 0.6, 0.3, 30, icp_reach_m=3.0)
    assert np.linalg.norm(whole.T_scene_model[:3, 3] - T[:3, 3]) > 0.2  # ICP did move it
    assert whole.overlap > 0.9
    assert np.array_equal(near.T_scene_model, whole.T_scene_model)
    assert (near.overlap, near.clutter) == (whole.overlap, whole.clutter)
    # nothing within reach: the hypothesis stays where RANSAC put it, as on the whole scene
    T_far = np.eye(4)
    T_far[:3, 3] = [500.0, 0.0, 0.0]
    far_whole = _verify(model, scene, T_far, 0.6, 0.3, 30)
    far_near = _verify(model, scene, T_far, 0.6, 0.3, 30, icp_reach_m=3.0)
    assert np.array_equal(far_near.T_scene_model, T_far)
    assert np.array_equal(far_whole.T_scene_model, T_far)


def test_verify_refines_again_on_the_whole_scene_a_hypothesis_that_moves_beyond_reach():
    # a flat 2 x 2 m patch placed 1.5 m off itself: ICP crawls back over a metre, and the part of
    # the scene it ends on lies beyond the neighbourhood of where it started
    g = np.arange(0.0, 2.0001, 0.1)
    patch = np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)
    T = np.eye(4)
    T[0, 3] = 1.5
    whole = _verify(patch, patch, T, 0.6, 0.3, 100)
    assert whole.T_scene_model[0, 3] < 0.5
    start = patch.mean(0) + T[:3, 3]
    reach_m = 0.05
    radius = np.linalg.norm(patch - patch.mean(0), axis=1).max() + 0.6 + reach_m
    crop = patch[np.linalg.norm(patch - start, axis=1) <= radius]
    assert not np.array_equal(
        _verify(patch, crop, T, 0.6, 0.3, 100).T_scene_model, whole.T_scene_model
    )
    near = _verify(patch, patch, T, 0.6, 0.3, 100, icp_reach_m=reach_m)
    assert np.array_equal(near.T_scene_model, whole.T_scene_model)


def _corner(g: np.ndarray) -> np.ndarray:
    """Three square planes sampled on the grid ``g``: z=0, x=0 and y=0, meeting at the origin."""
    floor = np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)
    return np.vstack([floor, floor[:, [2, 0, 1]], floor[:, [0, 2, 1]]])


def _corner_fit_case() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A corner scene with its normals, the model sampled half a cell off it, a start pose 5 cm off."""
    g = np.arange(0.0, 2.0001, 0.1)
    scene, model = _corner(g), _corner(g[:-1] + 0.05)
    normals = np.repeat(np.eye(3)[[2, 0, 1]], len(scene) // 3, axis=0)
    T = np.eye(4)
    T[:3, 3] = [0.03, 0.02, 0.04]
    return scene, normals, model, T


def test_point_to_plane_verify_uses_the_scenes_own_normals():
    # a corner of three planes, the model sampled half a cell off the scene's samples: fitted to the
    # points ICP snaps the model's samples onto the scene's (a third of a cell off along each axis);
    # fitted to the planes through the normals the scene carries it lands on the surfaces. (A flat
    # patch would leave Open3D's solve without one answer: see the guard's test below.)
    scene, normals, model, T = _corner_fit_case()
    to_planes = verify_with_icp(
        PointSet(model),
        PointSet(scene, normals=normals),
        T,
        VerifySettings(0.6, 0.3, 30, point_to_plane=True),
    ).T_scene_model
    to_points = verify_with_icp(
        PointSet(model), PointSet(scene), T, VerifySettings(0.6, 0.3, 30)
    ).T_scene_model
    assert np.linalg.norm(to_planes[:3, 3]) < 0.01, to_planes[:3, 3]
    assert np.linalg.norm(to_points[:3, 3]) > 0.04, to_points[:3, 3]


def test_point_to_plane_verify_fits_a_noisy_scene_to_its_points():
    # planes where the scene's median sigma is within the gate, points where it is above; on the
    # corner of the test above, where both fits have one answer and they differ by centimetres
    scene, normals, model, T = _corner_fit_case()

    def fit(sigma_m: float, **kw) -> np.ndarray:
        noisy = PointSet(scene, np.full(len(scene), sigma_m), normals)
        return verify_with_icp(PointSet(model), noisy, T, VerifySettings(0.6, 0.3, 30, **kw))

    gate = {"point_to_plane": True, "plane_max_sigma_m": 0.3}
    to_points = fit(0.1).T_scene_model
    assert np.allclose(fit(0.5, **gate).T_scene_model, to_points)
    to_planes = fit(0.1, **gate).T_scene_model
    assert np.linalg.norm(to_planes[:3, 3]) < 0.01, to_planes[:3, 3]
    assert np.linalg.norm(to_points[:3, 3]) > 0.04, to_points[:3, 3]


def test_normal_spread_is_a_third_for_a_corner_and_zero_for_one_or_two_planes():
    axes = np.eye(3)
    assert abs(normal_spread(np.repeat(axes, 50, axis=0)) - 1 / 3) < 1e-12
    assert normal_spread(np.repeat(axes[[2]], 50, axis=0)) < 1e-12  # flat ground
    assert normal_spread(np.repeat(axes[[0, 2]], 50, axis=0)) < 1e-12  # a wall on the ground
    assert normal_spread(np.zeros((0, 3))) == 0.0
    # a roof over a box: the sides' few normals are what holds the fit along the ground
    box = np.vstack([np.repeat(axes[[2]], 90, axis=0), np.repeat(axes[[0, 1]], 5, axis=0)])
    assert abs(normal_spread(box) - 0.05) < 1e-12


def test_point_to_plane_verify_fits_one_plane_to_its_points():
    # one plane leaves the fit free along it, where Open3D's solve has no unique answer: the points
    # decide there, every time the same, and the corner (three planes) is still fitted to its planes
    g = np.arange(0.0, 2.0001, 0.1)
    flat = np.stack(np.meshgrid(g, g, [0.0]), -1).reshape(-1, 3)
    up = np.tile(np.float64([0, 0, 1]), (len(flat), 1))
    T = np.eye(4)
    T[:3, 3] = [0.04, 0.03, 0.2]
    planes = VerifySettings(0.6, 0.3, 30, point_to_plane=True, plane_min_spread=0.01)
    fits = [
        verify_with_icp(PointSet(flat), PointSet(flat, normals=up), T, planes) for _ in range(5)
    ]
    to_points = verify_with_icp(PointSet(flat), PointSet(flat), T, VerifySettings(0.6, 0.3, 30))
    for fit in fits:
        assert np.array_equal(fit.T_scene_model, to_points.T_scene_model)
    scene, normals, model, T = _corner_fit_case()
    corner = verify_with_icp(PointSet(model), PointSet(scene, normals=normals), T, planes)
    assert np.linalg.norm(corner.T_scene_model[:3, 3]) < 0.01, corner.T_scene_model[:3, 3]


def test_point_to_plane_verify_on_the_neighbourhood_equals_verify_on_the_whole_scene():
    # the neighbourhood's normals are the rows of the scene's own normals that it keeps
    model, points = _box_on_wide_ground(5)
    normals = estimate_normals(points, 10, None)
    T = np.eye(4)
    T[:3, 3] = [20.3, 9.8, 0.1]
    fits = [
        verify_with_icp(
            PointSet(model),
            PointSet(points, normals=normals),
            T,
            VerifySettings(0.6, 0.3, 30, icp_reach_m=reach_m, point_to_plane=True),
        )
        for reach_m in (None, 3.0)
    ]
    assert np.linalg.norm(fits[0].T_scene_model[:3, 3] - [20.0, 10.0, 0.0]) < 0.1
    assert np.allclose(fits[1].T_scene_model, fits[0].T_scene_model, atol=1e-9)


def test_verify_does_not_count_a_points_own_noise_as_clutter():
    model = _box_surface(0.3)
    rng = np.random.default_rng(0)
    # the top face seen from far away: depth noise of 0.5 m (1 sigma), far beyond the 0.3 m overlap
    top = model[model[:, 2] == 2.0]
    noisy = top - np.array([0.0, 0.0, 0.5]) * np.abs(rng.normal(size=(len(top), 1)))
    without = _verify(model, noisy, np.eye(4), 0.6, 0.3, 0)
    sigma = np.full(len(noisy), 0.5)
    with_sigma = _verify(
        model, noisy, np.eye(4), 0.6, 0.3, 0, scene_sigma_m=sigma, k_clutter_sigma=2.0
    )
    assert without.clutter > 0.4
    assert with_sigma.clutter < 0.1
    # a precise point that lies off the model stays clutter however noisy the others are
    pole = np.array([[3.0, 1.5, 1.0]])
    sigma_pole = np.concatenate([sigma, [0.01]])
    v = _verify(
        model,
        np.concatenate([noisy, pole]),
        np.eye(4),
        0.6,
        0.3,
        0,
        scene_sigma_m=sigma_pole,
        k_clutter_sigma=2.0,
    )
    assert v.clutter * (len(noisy) + 1) >= 1 - 1e-9


def test_point_to_plane_verify_gives_the_same_bytes_whatever_the_threads():
    # Open3D sums the point-to-plane normal equations over its threads, in an order that depends on
    # how many run; verification must not: a replay of a recording gives byte-identical detections on a
    # loaded machine too (determinism contract). Its own thread setting is left as it was.
    model, points = _box_on_wide_ground(7)
    normals = estimate_normals(points, 10, None)
    T = np.eye(4)
    T[:3, 3] = [20.3, 9.8, 0.1]
    planes = VerifySettings(0.6, 0.3, 30, point_to_plane=True)
    scene = PointSet(points, normals=normals)
    before = o3d.utility.get_max_threads()
    fits = []
    try:
        for threads in (1, 2, 1, 2):
            o3d.utility.set_max_threads(threads)
            setting = o3d.utility.get_max_threads()  # capped at the machine's
            fits.append(verify_with_icp(PointSet(model), scene, T, planes).T_scene_model)
            assert o3d.utility.get_max_threads() == setting
    finally:
        o3d.utility.set_max_threads(before)
    assert np.linalg.norm(fits[0][:3, 3] - [20.0, 10.0, 0.0]) < 0.1
    assert all(fit.tobytes() == fits[0].tobytes() for fit in fits)
