"""The tracker: association, confirmation, fusion, heading ambiguity, ageing, bad input, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atr.config import load_config
from atr.errors import ConfigError, InputError
from atr.tracking import Tracker, TrackingConfig, TrackInput
from atr.tracking.tracker import geometric_median

STEP_NS = 500_000_000
TARGET_M = np.array([12.0, -7.0, 0.0])
TARGET_YAW = 0.7


def det(p, yaw=None, target="t72") -> TrackInput:
    return TrackInput(target, np.asarray(p, np.float64), yaw)


def stamp(k: int) -> int:
    return 1_000_000_000 + k * STEP_NS


def orbit_scenes(seed: int, scenes: int = 80, sigma_m: float = 0.4, p_detect: float = 0.8):
    """Noisy detections of one target along an orbit, missed scenes, and clutter false positives
    scattered over the 200 m around it with random headings (about one every other scene)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(scenes):
        ds = []
        if rng.random() < p_detect:
            ds.append(det(TARGET_M + rng.normal(0, sigma_m, 3), TARGET_YAW + rng.normal(0, 0.1)))
        if rng.random() < 0.5:
            ds.append(det(rng.uniform(-100, 100, 3) * [1, 1, 0], rng.uniform(-math.pi, math.pi)))
        rng.shuffle(ds)
        out.append(ds)
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_orbit_one_confirmed_target_fused_better_than_a_detection(seed):
    tracker = Tracker()
    errors, confirmed_ids, first_confirmed = [], set(), None
    for k, ds in enumerate(orbit_scenes(seed)):
        errors += [
            np.linalg.norm(d.position_m - TARGET_M)
            for d in ds
            if d.yaw_rad is not None and np.linalg.norm(d.position_m - TARGET_M) < 3
        ]
        tracks = tracker.update(ds, stamp(k))
        for t in tracks:
            if t.state != "tentative":
                confirmed_ids.add(t.id)
                if first_confirmed is None:
                    first_confirmed = k
    assert len(confirmed_ids) == 1, "clutter never recurs at one place: one confirmed track"
    (track,) = [t for t in tracker.tracks if t.id in confirmed_ids]
    fused_error = np.linalg.norm(track.position_m - TARGET_M)
    assert fused_error < 0.5 * np.median(errors)
    assert abs(math.remainder(track.yaw_rad - TARGET_YAW, 2 * math.pi)) < 0.05
    assert first_confirmed is not None and first_confirmed <= 3
    assert track.hits > 50 and len(track.supporting_stamps_ns) == TrackingConfig().supporting_max
    # the covariance says it is known better than one detection (steady state of the random walk)
    assert np.all(np.linalg.eigvalsh(track.P_position) < TrackingConfig().position_sigma_m ** 2 / 5)
    assert track.covariance.shape == (4, 4)


def test_two_targets_keep_their_tracks_whatever_the_detection_order():
    a, b = np.array([0.0, 0, 0]), np.array([6.0, 0, 0])
    tracker = Tracker()
    for k in range(6):
        ds = [det(a, 0.0), det(b, 1.0)]
        tracker.update(ds[::-1] if k % 2 else ds, stamp(k))
    assert [(t.id, t.state, t.hits) for t in tracker.tracks] == [
        (1, "confirmed", 6),
        (2, "confirmed", 6),
    ]
    np.testing.assert_allclose(tracker.tracks[0].position_m, a)
    np.testing.assert_allclose(tracker.tracks[1].position_m, b)


def test_classes_do_not_mix():
    tracker = Tracker()
    for k in range(3):
        tracker.update([det([0, 0, 0], 0.0, "t72"), det([0.3, 0, 0], 0.0, "truck6x6")], stamp(k))
    assert sorted(t.target for t in tracker.tracks) == ["t72", "truck6x6"]


def test_m_of_n_confirmation_and_tentative_deletion():
    tracker = Tracker(TrackingConfig(confirm_hits=2, confirm_window=3))
    assert tracker.update([det([0, 0, 0])], stamp(0))[0].state == "tentative"
    assert tracker.update([], stamp(1))[0].state == "tentative"  # 1 of 2, may still reach 2 of 3
    assert tracker.update([det([0.1, 0, 0])], stamp(2))[0].state == "confirmed"
    lone = Tracker()
    lone.update([det([0, 0, 0])], stamp(0))
    lone.update([], stamp(1))
    assert lone.update([], stamp(2)) == []  # cannot reach 2 of 3 any more


def test_confirmed_track_goes_lost_then_is_deleted():
    config = TrackingConfig(delete_after_misses=3, miss_patience_per_hit=0.0)
    tracker = Tracker(config)
    for k in range(3):
        tracker.update([det([0, 0, 0])], stamp(k))
    states = [[t.state for t in tracker.update([], stamp(k))] for k in range(3, 6)]
    assert states == [["lost"], ["lost"], []]
    # a lost track seen again is confirmed again, same id
    tracker = Tracker(config)
    for k in range(3):
        tracker.update([det([0, 0, 0])], stamp(k))
    tracker.update([], stamp(3))
    (track,) = tracker.update([det([0.2, 0, 0])], stamp(4))
    assert (track.id, track.state) == (1, "confirmed")


def test_a_track_seen_often_outlives_more_misses():
    """miss_patience_per_hit: six hits at 1 per hit keep a track through five misses where
    delete_after_misses = 3 alone deletes it after three; a track seen twice still goes after three."""
    config = TrackingConfig(delete_after_misses=3, miss_patience_per_hit=1.0)
    often, twice = Tracker(config), Tracker(config)
    for k in range(6):
        often.update([det([0, 0, 0])], stamp(k))
    for k in range(2):
        twice.update([det([0, 0, 0])], stamp(k))
    assert [len(often.update([], stamp(k))) for k in range(6, 12)] == [1, 1, 1, 1, 1, 0]
    assert [len(twice.update([], stamp(k))) for k in range(2, 5)] == [1, 1, 0]


def test_a_gap_of_many_scenes_ages_tracks_by_the_scenes_it_spans():
    tracker = Tracker()
    for k in range(4):
        tracker.update([det([0, 0, 0])], stamp(k))
    # 40 scene periods later the old track is gone; the detection starts a new one
    (track,) = tracker.update([det([0, 0, 0])], stamp(44))
    assert (track.id, track.state) == (2, "tentative")
    # a short gap (2 periods) only coasts, and the widened covariance still lets it associate
    tracker = Tracker()
    for k in range(4):
        tracker.update([det([0, 0, 0])], stamp(k))
    (track,) = tracker.update([det([1.0, 0, 0])], stamp(6))
    assert (track.id, track.state) == (1, "confirmed")


def test_heading_gate_and_one_vehicle_per_place():
    for place_hits, hits, state in ((False, 3, "lost"), (True, 4, "confirmed")):
        tracker = Tracker(TrackingConfig(place_hits=place_hits))
        for k in range(3):
            tracker.update([det([0, 0, 0], 0.0)], stamp(k))
        # the same place at 90 degrees: outside the heading gate, and no second track at its place;
        # with place_hits (the default) it is this vehicle seen with a wrong heading: a hit
        (track,) = tracker.update([det([0, 0, 0], math.pi / 2)], stamp(3))
        assert (track.id, track.hits, track.state) == (1, hits, state)
        assert track.yaw_rad == 0.0, "a heading outside the gate is never fused"


def test_heading_ambiguity_only_once_the_detections_show_it():
    config = TrackingConfig(flip_evidence=2, place_hits=False)
    tracker = Tracker(config)
    for k in range(3):
        tracker.update([det([0, 0, 0], 0.1)], stamp(k))
    hits = [tracker.update([det([0, 0, 0], 0.1 + math.pi)], stamp(k))[0].hits for k in (3, 4, 5)]
    track = tracker.tracks[0]
    assert hits == [3, 3, 4], "two flipped detections are evidence; the third is fused"
    assert track.yaw_ambiguous and len(tracker.tracks) == 1
    assert abs(math.remainder(track.yaw_rad - 0.1, math.pi)) < 1e-9


def test_a_turned_detection_at_the_place_is_a_hit_with_place_hits():
    # a new vehicle seen next with its ends swapped: without place_hits that scene is a miss
    scenes = [det([0, 0, 0], 0.1), det([0.3, 0, 0], 0.1 + math.pi), det([0.3, 0, 0], 0.1)]
    states = {}
    for place_hits in (False, True):
        tracker = Tracker(TrackingConfig(place_hits=place_hits))
        states[place_hits] = [tracker.update([d], stamp(k))[0].state for k, d in enumerate(scenes)]
        track = tracker.tracks[0]
        assert abs(track.yaw_rad - 0.1) < 0.05, "a turned detection's heading is not fused"
    assert states[False] == ["tentative", "tentative", "confirmed"]
    assert states[True] == ["tentative", "confirmed", "confirmed"]
    assert track.hits == 3 and 0.1 < track.position_m[0] < 0.3, "its position was fused"


def test_bad_input_is_refused_and_leaves_the_tracks_unchanged():
    tracker = Tracker()
    tracker.update([det([0, 0, 0], 0.0)], stamp(0))
    before = [(t.id, t.hits, t.position_m.tolist()) for t in tracker.tracks]
    with pytest.raises(InputError, match="nan"):
        tracker.update([det([0, 0, 0], 0.0), det([np.nan, 0, 0], 0.0)], stamp(1))
    with pytest.raises(InputError, match="heading"):
        tracker.update([det([0, 0, 0], float("inf"))], stamp(1))
    with pytest.raises(InputError, match="not after"):
        tracker.update([det([0, 0, 0], 0.0)], stamp(0))
    with pytest.raises(InputError, match="3 finite metres"):
        tracker.update([det([0, 0], 0.0)], stamp(1))
    with pytest.raises(InputError, match="score nan"):
        tracker.update([TrackInput("t72", np.zeros(3), 0.0, float("nan"))], stamp(1))
    assert [(t.id, t.hits, t.position_m.tolist()) for t in tracker.tracks] == before
    assert tracker.update([det([0, 0, 0], 0.0)], stamp(1))[0].state == "confirmed"


def test_same_inputs_same_tracks():
    def run():
        tracker = Tracker()
        return [
            [(t.id, t.state, t.T_world_target.tobytes(), t.covariance.tobytes()) for t in ts]
            for ts in (tracker.update(ds, stamp(k)) for k, ds in enumerate(orbit_scenes(5)))
        ]

    assert run() == run()


def test_config_group_and_validation():
    assert load_config(overrides=["tracking.confirm_hits=3"]).tracking.confirm_hits == 3
    with pytest.raises(ConfigError, match="confirm_hits"):
        load_config(overrides=["tracking.confirm_hits=4"])
    with pytest.raises(ConfigError, match="position_sigma_m"):
        TrackingConfig(position_sigma_m=0.0)


def test_from_pose_reads_the_heading():
    c, s = math.cos(2.0), math.sin(2.0)
    T = np.array([[c, -s, 0, 1], [s, c, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1.0]])
    d = TrackInput.from_pose("t72", T)
    assert d.yaw_rad == pytest.approx(2.0) and d.position_m.tolist() == [1, 2, 3]


def test_the_quick_far_test_never_rejects_a_pair_the_gate_accepts():
    """Gating first rejects pairs by |r|^2 > k^2 trace(S) without a solve; that bound must never
    drop a pair the exact Mahalanobis gate would take (else the fast tracker tracks differently)."""
    rng = np.random.default_rng(11)
    k2 = Tracker().config.k_gate ** 2
    near_edge = 0
    for _ in range(2000):
        tracker = Tracker()
        tracker.update([TrackInput("t72", rng.normal(0, 5, 3), 0.0)], 1)
        (track,) = tracker.tracks
        A = rng.normal(0, rng.uniform(0.05, 3.0), (3, 3))
        track.P_position = A @ A.T  # any covariance the filter could reach
        d = TrackInput("t72", track.position_m + rng.normal(0, rng.uniform(0.1, 10), 3), 0.0)
        inside = tracker._gates(track, d)[0] <= k2
        assert not inside or tracker._near(d) == [0]
        near_edge += inside
    assert 100 < near_edge < 1900  # both sides of the gate were exercised


def look_alike_orbit(seed: int, scenes: int = 30):
    """One T-72 whose place the matcher gives to the M1 in two scenes of every five, and a real M1
    parked 40 m away."""
    rng = np.random.default_rng(seed)
    m1_m = TARGET_M + [40.0, 0.0, 0.0]
    out = []
    for k in range(scenes):
        noise = rng.normal(0, 0.3, 3)
        if k % 5 in (1, 3):
            here = TrackInput("m1", TARGET_M + noise, TARGET_YAW, 0.7)
        else:
            here = TrackInput("t72", TARGET_M + noise, TARGET_YAW + rng.normal(0, 0.05), 0.8)
        out.append([here, TrackInput("m1", m1_m + rng.normal(0, 0.3, 3), -1.0, 0.9)])
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_class_votes_make_one_track_per_place_of_the_class_seen_most(seed):
    def established(votes: bool) -> list:
        tracker = Tracker(TrackingConfig(class_votes=votes))
        for k, ds in enumerate(look_alike_orbit(seed)):
            tracker.update(ds, stamp(k))
        return sorted(
            (t.target, round(float(t.position_m[0])))
            for t in tracker.tracks
            if t.state != "tentative"
        )

    x = round(float(TARGET_M[0]))
    # one vehicle per place: the T-72's place is one T-72 track, the parked M1 keeps its own
    assert established(True) == [("m1", x + 40), ("t72", x)]
    # per class, the look-alike's wins at the T-72's place make a second, M1 track there
    assert ("m1", x) in established(False)


def test_class_votes_weigh_the_matcher_scores():
    tracker = Tracker(TrackingConfig(class_votes=True))
    for k in range(6):
        weak, strong = (
            TrackInput("t72", TARGET_M, TARGET_YAW, 0.2),
            TrackInput("m1", TARGET_M, TARGET_YAW, 0.9),
        )
        tracker.update([weak if k % 3 else strong], stamp(k))  # four weak T-72s, two strong M1s
    (track,) = tracker.tracks
    assert track.target == "m1"
    assert track.class_evidence == pytest.approx({"m1": 1.8, "t72": 0.8})


def test_class_votes_keep_a_place_alive_through_a_turned_look_alike_without_turning_it():
    tracker = Tracker(TrackingConfig(class_votes=True))
    for k in range(4):
        tracker.update([det(TARGET_M, TARGET_YAW)], stamp(k))
    turned = TrackInput("m1", TARGET_M + [0.2, 0.0, 0.0], TARGET_YAW + math.pi / 2, 0.9)
    (track,) = tracker.update([turned], stamp(4))
    assert track.state == "confirmed" and track.hits == 5  # the place was seen: fused, not missed
    assert track.yaw_rad == pytest.approx(TARGET_YAW, abs=0.05)  # its heading did not pull
    assert track.target == "t72"


def test_a_place_confirms_as_a_class_only_once_that_class_recurs():
    """A place that look-alikes win in turn, each class once, is not yet a confirmed target of any."""

    def states(recurs: bool, classes: list[str]) -> list[tuple[str, str]]:
        tracker = Tracker(TrackingConfig(class_votes=True, class_recurs=recurs))
        history = []
        for k, name in enumerate(classes):
            (track,) = tracker.update([TrackInput(name, TARGET_M, TARGET_YAW, 0.5)], stamp(k))
            history.append((track.state, track.target))
        return history

    # two scenes, two classes: votes alone confirm the place on the second scene
    assert states(False, ["m1", "t72"])[-1][0] == "confirmed"
    assert states(True, ["m1", "t72"])[-1][0] == "tentative"
    # ... until its leading class has been seen confirm_hits (2) times
    assert states(True, ["m1", "t72", "t72"]) == [
        ("tentative", "m1"),
        ("tentative", "m1"),
        ("confirmed", "t72"),
    ]
    # per class (no votes) the rule changes nothing
    tracker = Tracker(TrackingConfig(class_recurs=True))
    for k in range(2):
        (track,) = tracker.update([TrackInput("t72", TARGET_M, TARGET_YAW, 0.5)], stamp(k))
    assert track.state == "confirmed"


@pytest.mark.parametrize("seed", [0, 1])
def test_geometric_median_is_the_least_summed_distance_and_ignores_the_world_axes(seed):
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    points = rng.normal(0, 0.2, (40, 3))
    points[:5] += [1.5, -1.0, 0.3]  # a few fits that slid
    y = geometric_median(points)
    # scipy's general minimiser of the same cost, from the mean, is the outside reference
    ref = minimize(lambda q: np.linalg.norm(points - q, axis=1).sum(), points.mean(0), tol=1e-10).x
    assert np.linalg.norm(y - ref) < 1e-3
    assert np.linalg.norm(y) < 0.5 * np.linalg.norm(points.mean(0))
    # a rotation of the points rotates the median (a coordinate-wise median would not follow)
    c, s = math.cos(0.6), math.sin(0.6)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert np.linalg.norm(geometric_median(points @ R.T) - R @ y) < 1e-3


def test_fused_median_moves_little_for_a_fit_that_slid_and_the_mean_by_its_share():
    def fused_after(fuse_median: bool) -> np.ndarray:
        tracker = Tracker(TrackingConfig(fuse_median=fuse_median))
        rng = np.random.default_rng(3)
        for k in range(20):
            tracker.update([det(TARGET_M + rng.normal(0, 0.05, 3), TARGET_YAW)], stamp(k))
        for k in range(20, 23):  # three scenes of a half-hidden vehicle: fits 1.2 m off
            tracker.update([det(TARGET_M + [1.2, 0.0, 0.0], TARGET_YAW)], stamp(k))
        (track,) = tracker.tracks
        assert track.state == "confirmed" and len(track.places_m) == 23
        return track.position_m

    assert np.linalg.norm(fused_after(True) - TARGET_M) < 0.05
    assert np.linalg.norm(fused_after(False) - TARGET_M) > 0.15


def test_the_median_runs_over_the_latest_fuse_window_detections():
    tracker = Tracker(TrackingConfig(fuse_window=5))
    for k in range(12):  # a vehicle that moved after scene 5: the median follows within the window
        p = TARGET_M if k < 6 else TARGET_M + [0.6, 0, 0]
        tracker.update([det(p, TARGET_YAW)], stamp(k))
    (track,) = tracker.tracks
    assert len(track.places_m) == 5
    assert np.allclose(track.position_m, TARGET_M + [0.6, 0, 0])


def test_the_median_weighted_along_the_lines_of_sight_is_the_least_summed_weighted_distance():
    from scipy.optimize import minimize

    rng = np.random.default_rng(4)
    points = rng.normal(0, 0.2, (30, 3))
    azimuth = rng.uniform(0, 2 * math.pi, 30)
    sights = np.column_stack([np.cos(azimuth), np.sin(azimuth), np.zeros(30)])
    sights[:3] = 0.0  # detections whose viewpoint is unknown weigh every direction alike
    w = 0.25
    W = np.eye(3) - (1 - w) * sights[:, :, None] * sights[:, None, :]

    def cost(q: np.ndarray) -> float:
        d = points - q
        return float(np.sqrt(np.einsum("ni,nij,nj->n", d, W, d)).sum())

    y = geometric_median(points, sights=sights, sight_weight=w)
    # scipy's general minimiser of the same cost is the outside reference
    ref = minimize(cost, points.mean(0), tol=1e-10).x
    assert np.linalg.norm(y - ref) < 1e-3
    assert cost(y) <= cost(points.mean(0))
    # weight 1 is the plain median
    assert np.allclose(
        geometric_median(points, sights=sights, sight_weight=1.0), geometric_median(points)
    )


def test_a_fit_offset_along_the_line_of_sight_is_fused_away_over_half_an_orbit():
    """Detections that sit 0.15 m beyond the vehicle as the camera sees it, over half an orbit: the
    plain median keeps most of that offset, the median that weighs the line of sight less does not."""

    def fused_error_m(weight: float) -> float:
        tracker = Tracker(TrackingConfig(fuse_line_of_sight_weight=weight))
        rng = np.random.default_rng(5)
        for k, azimuth in enumerate(np.linspace(0.0, math.pi, 25)):
            viewpoint = TARGET_M + 80.0 * np.array([math.cos(azimuth), math.sin(azimuth), 0.5])
            sight = (TARGET_M - viewpoint) * [1, 1, 0]
            sight /= np.linalg.norm(sight)
            p = TARGET_M + 0.15 * sight + rng.normal(0, 0.02, 3)
            tracker.update([TrackInput("t72", p, TARGET_YAW, 1.0, viewpoint)], stamp(k))
        (track,) = tracker.tracks
        return float(np.linalg.norm(track.position_m - TARGET_M))

    plain, weighted = fused_error_m(1.0), fused_error_m(0.25)
    assert plain > 0.08  # of 0.15 m: two thirds of it stay
    assert weighted < 0.5 * plain, (plain, weighted)


def test_from_pose_keeps_the_viewpoint_and_a_detection_without_one_has_no_line_of_sight():
    T = np.eye(4)
    T[:3, 3] = [10.0, 0.0, 0.0]
    seen = TrackInput.from_pose("t72", T, 0.9, viewpoint_m=[0.0, 0.0, 50.0])
    assert np.allclose(seen.line_of_sight(), [1.0, 0.0, 0.0])
    assert np.allclose(TrackInput.from_pose("t72", T).line_of_sight(), 0.0)
    overhead = TrackInput.from_pose("t72", T, viewpoint_m=[10.0, 0.0, 80.0])
    assert np.allclose(overhead.line_of_sight(), 0.0)
