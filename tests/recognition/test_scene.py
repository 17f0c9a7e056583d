"""Our steps around the paper's (atr.recognition.scene): an accepted ground vehicle is placed on the ground
beside it, which the low-percentile ground estimate under it is not."""

from dataclasses import replace

import numpy as np

from atr.recognition import RecognitionConfig
from atr.recognition.scene import GroundCheck, Scene, remove_ground, template_views
from atr.recognition.steps import PointSet


class _OnGround:
    params = {"on_ground": True}
    points_m = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.3]])  # a 2.3 m tall vehicle


def _noisy_ground_with_a_box(
    rng: np.random.Generator, ground_z_m: float, sigma_m: float = 0.1
) -> np.ndarray:
    """A noisy flat ground at ground_z_m (sigma_m: 0.1 m as SfM at 100 m) and a 3 x 3 x 2 m box on it."""
    ground = np.column_stack(
        [rng.uniform(-20, 20, (6000, 2)), ground_z_m + rng.normal(0.0, sigma_m, 6000)]
    )
    ground = ground[np.abs(ground[:, :2]).max(axis=1) > 1.5]  # hidden under the box
    box = np.column_stack([rng.uniform(-1.5, 1.5, (800, 2)), rng.uniform(0.3, 2.0, 800)])
    return np.vstack([ground, box + [0.0, 0.0, ground_z_m]])


def test_an_accepted_vehicle_is_placed_on_the_median_of_the_ground_around_it():
    rng = np.random.default_rng(4)
    config = RecognitionConfig()
    points = _noisy_ground_with_a_box(rng, ground_z_m=1.0)
    scene = remove_ground(
        Scene(PointSet(points), np.array([0.0, -80.0, 40.0])), [_OnGround()], config, {}
    )
    check = GroundCheck(scene, config)
    sunk = np.eye(4)
    sunk[2, 3] = 0.7  # ICP left the vehicle 0.3 m low
    placed = check.placed(sunk)
    assert abs(placed[2, 3] - 1.0) < 0.03  # the ground's median, not its low percentile
    np.testing.assert_array_equal(placed[:2], sunk[:2])  # heading and x, y untouched
    # the estimate under the vehicle the matcher grouped with stands lower than the ground
    assert np.median(scene.surface.points_m[:, 2] - scene.height) < 0.95


def test_in_a_noisier_cloud_the_placement_settles_on_the_ground_not_below_it():
    """The ground points are cut at a low percentile plus the ground cut, so with sigma 0.2 m their
    median stands low; the band about the estimate (``k_place_band``) brings it back to the ground."""
    config = RecognitionConfig()
    ground_points_only = replace(config, ground=replace(config.ground, k_place_band=0.0))
    sunk = np.eye(4)
    sunk[2, 3] = 0.7
    for seed in range(3):
        points = _noisy_ground_with_a_box(np.random.default_rng(seed), 1.0, sigma_m=0.2)
        scene = remove_ground(
            Scene(PointSet(points), np.array([0.0, -80.0, 40.0])), [_OnGround()], config, {}
        )
        assert GroundCheck(scene, ground_points_only).placed(sunk)[2, 3] < 1.0 - 0.1
        placed = GroundCheck(scene, config).placed(sunk)
        assert abs(placed[2, 3] - 1.0) < 0.05
        np.testing.assert_array_equal(placed[:2], sunk[:2])


def test_without_ground_in_reach_the_height_stays_as_icp_left_it():
    rng = np.random.default_rng(5)
    config = RecognitionConfig()
    points = _noisy_ground_with_a_box(rng, ground_z_m=0.0)
    scene = remove_ground(Scene(PointSet(points), None), [_OnGround()], config, {})
    far = np.eye(4)
    far[:3, 3] = (200.0, 0.0, -0.4)  # nowhere near the cloud
    np.testing.assert_array_equal(GroundCheck(scene, config).placed(far), far)


class _TwelveViewsOnThreeRings:
    """A template's view layout: azimuths every 90 deg on rings at 0, 10 and 35 deg elevation."""

    params = {
        "view_azimuths_deg": [0.0, 90.0, 180.0, 270.0] * 3,
        "view_elevations_deg": [0.0] * 4 + [10.0] * 4 + [35.0] * 4,
    }

    def view_slices(self) -> list[tuple[slice, slice]]:
        return [(slice(i, i + 1), slice(i, i + 1)) for i in range(12)]


def test_a_keypoint_meets_its_nearest_ring_and_every_ring_within_reach():
    """Keypoints at 2 m height seen from 50 m away at 2.3 and at 15 deg of camera elevation."""
    keypoints = np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [2.0, 0.0, 2.0]])
    scene = Scene(PointSet(keypoints), np.array([0.0, -50.0, 4.0]), band=np.ones(3, bool))
    scene.kp_idx = np.array([0, 1, 2])
    views = template_views(_TwelveViewsOnThreeRings(), scene)
    assert {r: list(k) for r, k in views.keypoints_of_ring.items()} == {
        0.0: [0, 1, 2],
        10.0: [],
        35.0: [],
    }
    reach = template_views(_TwelveViewsOnThreeRings(), scene, ring_reach_deg=10.0)
    assert {r: list(k) for r, k in reach.keypoints_of_ring.items()} == {
        0.0: [0, 1, 2],
        10.0: [0, 1, 2],  # 7.7 deg from 2.3 deg
        35.0: [],
    }
    scene.viewpoint_m = np.array([0.0, -50.0, 2.0 + 50.0 * np.tan(np.radians(15.0))])
    reach = template_views(_TwelveViewsOnThreeRings(), scene, ring_reach_deg=10.0)
    # 15 deg: the 10 deg ring (nearest) only; 0 and 35 deg lie 15 and 20 deg off
    assert [len(k) for k in reach.keypoints_of_ring.values()] == [0, 3, 0]
