"""Track-guided search: the held tracks' neighbourhoods between whole-cloud searches, and the same answer.

The tests before the lagged ones set ``whole_search_lag_frames=0``: a whole search answers its own scene.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from concurrent.futures import Future

import numpy as np
import pytest

from atr.recognition import RecognitionConfig, RecognitionResult, build_template, recognize
from atr.recognition import synthetic as syn
from atr.recognition._backend import have_descriptor
from atr.regions import SearchRegion
from atr.tracking import TrackingConfig, TrackInput
from atr.tracking.guided_search import GuidedSearch, SearchSchedule
from atr.tracking.lane import WholeSearch

DESC = "shot" if have_descriptor("shot") else "fpfh"
AZ, EL, RANGE = np.radians(20.0), np.radians(30.0), 50.0
VIEWPOINT = RANGE * np.array([np.cos(EL) * np.cos(AZ), np.cos(EL) * np.sin(AZ), np.sin(EL)])
TRUCK_SHIFT_M = np.array([45.0, 0.0, 0.0])  # the truck's scene, beside the tank's, far from it
SCENE_S = 1_000_000_000


@pytest.fixture(scope="module")
def world():
    sim = pytest.importorskip("atr.sim.vehicles")
    cfg = RecognitionConfig(descriptor=DESC)
    meshes = {"t72": sim.t72(), "truck6x6": sim.truck_6x6()}
    templates = [build_template(m.vertices, m.triangles, k, DESC, cfg) for k, m in meshes.items()]
    T_tank = syn.pose(0.0, -2.0, 0.7)
    tank = syn.aerial_scene(
        [((meshes["t72"].vertices, meshes["t72"].triangles), T_tank)],
        seed=0,
        samples_per_m2=30,
        extent_m=15,
        n_clutter=4,
        azimuth_deg=20,
    )
    truck = syn.aerial_scene(
        [((meshes["truck6x6"].vertices, meshes["truck6x6"].triangles), syn.pose(0.0, 0.0, 0.2))],
        seed=1,
        samples_per_m2=30,
        extent_m=15,
        n_clutter=4,
        azimuth_deg=20,
    )
    scene = np.vstack([tank, truck + TRUCK_SHIFT_M])
    return cfg, templates, scene, T_tank[:3, 3]


def _tank_found(result, position_m) -> bool:
    return any(
        d.target == "t72" and np.linalg.norm(d.T_world_target[:3, 3] - position_m) < 2.0
        for d in result.detections
    )


def test_held_tracks_are_searched_between_whole_searches(world) -> None:
    cfg, templates, scene, tank_m = world
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=3, whole_search_lag_frames=0
    )
    search = GuidedSearch(templates, cfg, tracking)
    searches, points = [], []
    for k in range(1, 6):
        result = search(scene, seed=0, stamp_ns=k * SCENE_S, frame_seq=k, viewpoint_m=VIEWPOINT)
        searches.append(result.stats["search"])
        points.append(result.stats["searched_points"])
        assert _tank_found(result, tank_m), (k, result.stats["search"])
    # two scenes to confirm (M = 2): the whole cloud, then the tentative track tried where it stands
    # (its cloud matched whole, so the period counts from it); two guided scenes; the whole cloud again
    assert searches[:2] == ["whole", "tentative"] and searches[4] == "whole"
    assert all(isinstance(s, int) and s >= 1 for s in searches[2:4]), searches
    assert points[1] < len(scene) and points[2] < len(scene) and points[3] < len(scene)
    assert points[0] == points[4] == len(scene)
    # a scene out of order does not fail the recognition; the guidance starts again from no track
    late = search(scene, seed=0, stamp_ns=2 * SCENE_S, frame_seq=2, viewpoint_m=VIEWPOINT)
    assert _tank_found(late, tank_m)
    assert search.regions(3) is None


def _whole_frames(schedule: SearchSchedule, frames: range) -> list[int]:
    held = [SearchRegion(np.zeros(2), 5.0, -1.0, 4.0)]  # a track is held from the start
    whole = []
    for k in frames:
        regions = schedule.regions(held, k)
        schedule.searched(whole=regions is None, frame_seq=k)
        whole += [k] if regions is None else []
    return whole


def test_the_schedule_counts_frames_not_scenes() -> None:
    """A flight whose every pair is a scene and one sampled every fifth pair search whole at the same
    frames; a frame before the last whole search (another flight, a replay) is searched whole."""
    every_scene = _whole_frames(SearchSchedule(20), range(0, 100))
    every_fifth = _whole_frames(SearchSchedule(20), range(0, 100, 5))
    assert every_scene == every_fifth == [0, 20, 40, 60, 80]
    assert _whole_frames(SearchSchedule(20), range(3, 100, 10)) == [3, 23, 43, 63, 83]
    schedule = SearchSchedule(20)
    _whole_frames(schedule, range(50, 60))
    assert schedule.regions([SearchRegion(np.zeros(2), 5.0, -1.0, 4.0)], 7) is None
    assert schedule.regions([], 55) is None  # nothing held: whole


def test_without_guidance_it_is_recognize(world) -> None:
    cfg, templates, scene, _ = world
    search = GuidedSearch(templates, cfg, TrackingConfig(guided_search=False))
    for k in (1, 2, 3):
        guided = search(scene, seed=k, stamp_ns=k * SCENE_S, frame_seq=k, viewpoint_m=VIEWPOINT)
        plain = recognize(scene, templates, cfg, seed=k, viewpoint_m=VIEWPOINT)
        assert guided.stats["search"] == "whole"
        assert [d.to_dict() for d in guided.detections] == [d.to_dict() for d in plain.detections]
    assert search.regions(4) is None


def test_a_matcher_that_holds_no_track_searches_the_regions_it_is_given(world) -> None:
    """A restarted matcher meets clouds sfm matched around the tracks its predecessor held: it finds the
    targets there with every template instead of confirming nothing."""
    cfg, templates, scene, tank_m = world
    region = SearchRegion(tank_m[:2].copy(), 8.0, -1.0, 4.0)
    search = GuidedSearch(templates, cfg, TrackingConfig(guided_search=True))
    assert not search.tracker.tracks
    found = search(
        scene, seed=0, stamp_ns=SCENE_S, frame_seq=1, viewpoint_m=VIEWPOINT, cloud_regions=[region]
    )
    assert found.stats["search"] == 1 and found.stats["searched_points"] < len(scene)
    assert _tank_found(found, tank_m)
    assert search.tracker.tracks  # and it holds the tank again


def test_a_cloud_matched_whole_is_searched_where_the_schedule_says(world) -> None:
    """At the camera's pace sfm matches pairs whole until the matcher's guidance reaches it: a matcher
    that holds its target confirms it in those clouds, and searches whole only when its schedule says."""
    cfg, templates, scene, tank_m = world
    search = GuidedSearch(
        templates,
        cfg,
        TrackingConfig(guided_search=True, full_search_every_frames=3, whole_search_lag_frames=0),
    )
    searches = []
    for k in range(1, 6):
        result = search(
            scene,
            seed=0,
            stamp_ns=k * SCENE_S,
            frame_seq=k,
            viewpoint_m=VIEWPOINT,
            cloud_regions=[],
        )
        searches.append(result.stats["search"])
        assert _tank_found(result, tank_m), (k, result.stats["search"])
    assert searches == ["whole", "tentative", 1, 1, "whole"]


def test_the_scene_after_a_held_target_went_unconfirmed_is_searched_whole(world) -> None:
    cfg, templates, scene, tank_m = world
    for reacquire in (True, False):
        tracking = TrackingConfig(
            guided_search=True,
            full_search_every_frames=10,
            guided_reacquire_misses=int(reacquire),
            whole_search_lag_frames=0,
        )
        search = GuidedSearch(templates, cfg, tracking)
        for k in (1, 2):  # two whole scenes confirm the tank
            search(scene, seed=0, stamp_ns=k * SCENE_S, frame_seq=k, viewpoint_m=VIEWPOINT)
        assert search.regions(3) is not None
        nothing = search(np.zeros((0, 3)), seed=0, stamp_ns=3 * SCENE_S, frame_seq=3)
        assert nothing.stats["search"] != "whole" and not nothing.detections
        # the tank's track went unconfirmed: look everywhere once, then confirm it where it stands
        assert (search.regions(4) is None) == reacquire
        found = search(scene, seed=0, stamp_ns=4 * SCENE_S, frame_seq=4, viewpoint_m=VIEWPOINT)
        assert (found.stats["search"] == "whole") == reacquire
        assert _tank_found(found, tank_m)
        assert search.regions(5) is not None


def test_a_whole_search_also_lays_every_template_at_the_held_places(world) -> None:
    """A place a look-alike's template won is laid with every template again in the whole scenes, so the
    place competition can give it back; guided scenes lay only the classes held there."""
    cfg, templates, scene, tank_m = world
    for lays_all in (True, False):
        tracking = TrackingConfig(
            guided_search=True,
            full_search_every_frames=3,
            guided_whole_lays_all=lays_all,
            whole_search_lag_frames=0,
        )
        search = GuidedSearch(templates, cfg, tracking)
        for k in (1, 2):  # the tank's place held as the truck's: the look-alike won it twice
            search.tracker.update([TrackInput("truck6x6", tank_m, yaw_rad=0.7)], k * SCENE_S)
        search.schedule.searched(whole=True, frame_seq=0)  # frame 3 is whole again
        result = search(scene, seed=0, stamp_ns=3 * SCENE_S, frame_seq=3, viewpoint_m=VIEWPOINT)
        assert result.stats["search"] == "whole"
        if lays_all:
            laid = {t["target"]: t["hypotheses"] for t in result.stats["laid"]}
            assert laid == {"t72": 1, "truck6x6": 1}
        else:
            assert "laid" not in result.stats
        assert _tank_found(result, tank_m)


def test_a_tentative_track_whose_class_wins_its_place_again_skips_the_whole_search(world) -> None:
    """try_tentative_first: the scene after the first find lays the templates at the tentative
    tracks and, each won again by its own class, answers from their cylinders alone."""
    cfg, templates, scene, tank_m = world
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=10, whole_search_lag_frames=0
    )
    search = GuidedSearch(templates, cfg, tracking)
    first = search(scene, seed=0, stamp_ns=SCENE_S, frame_seq=1, viewpoint_m=VIEWPOINT)
    assert first.stats["search"] == "whole" and _tank_found(first, tank_m)
    assert all(t.state == "tentative" for t in search.tracker.tracks)
    tried = search(scene, seed=0, stamp_ns=2 * SCENE_S, frame_seq=2, viewpoint_m=VIEWPOINT)
    assert tried.stats["search"] == "tentative" and tried.stats["tentative_won"]
    assert tried.stats["tentative_templates"] == len(templates)  # every template competed there
    assert tried.stats["searched_points"] < len(scene)
    assert _tank_found(tried, tank_m)
    assert search.regions(3) is not None  # two scenes confirmed the tank: guided from here
    # the schedule counted the tried scene as whole (sfm matched its pair whole)
    assert search.regions(11) is not None and search.regions(12) is None


def test_a_tentative_track_not_won_again_leaves_the_scene_to_the_whole_search(world) -> None:
    cfg, templates, scene, tank_m = world
    # a third template no track is of: a try that fails stops at the tracks' own classes
    templates = [*templates, dataclasses.replace(templates[1], target="decoy")]
    tracking = TrackingConfig(guided_search=True, whole_search_lag_frames=0)
    search = GuidedSearch(templates, cfg, tracking)
    first = search(scene, seed=0, stamp_ns=SCENE_S, frame_seq=1, viewpoint_m=VIEWPOINT)
    own = {t.target for t in search.tracker.tracks}
    assert "decoy" not in own and _tank_found(first, tank_m)
    moved_m = np.array([0.0, 25.0, 0.0])  # the next scene's vehicles stand elsewhere
    moved = search(
        scene + moved_m, seed=0, stamp_ns=2 * SCENE_S, frame_seq=2, viewpoint_m=VIEWPOINT
    )
    assert moved.stats["search"] == "whole" and moved.stats["tentative_won"] is False
    assert moved.stats["tentative_templates"] == len(own) < len(templates)
    assert _tank_found(moved, tank_m + moved_m)
    # the scene's answer is the whole search's, as without the try
    plain = GuidedSearch(templates, cfg, dataclasses.replace(tracking, try_tentative_first=False))
    plain(scene, seed=0, stamp_ns=SCENE_S, frame_seq=1, viewpoint_m=VIEWPOINT)
    alone = plain(scene + moved_m, seed=0, stamp_ns=2 * SCENE_S, frame_seq=2, viewpoint_m=VIEWPOINT)
    assert [d.to_dict() for d in moved.detections] == [d.to_dict() for d in alone.detections]
    assert "tentative_won" not in alone.stats


def test_search_radius_is_a_multiple_of_the_largest_footprint(world) -> None:
    cfg, templates, _, _ = world

    def radius_m(k: float) -> float:
        tracking = dataclasses.replace(TrackingConfig(guided_search=True), k_search_radius=k)
        return GuidedSearch(templates, cfg, tracking).radius_m

    assert radius_m(2.0) == pytest.approx(2.0 * radius_m(1.0))
    # a template reaches no further from its origin than the default cylinder at any heading, and a
    # cylinder is never smaller than that reach, however small k is
    reach_m = max(float(np.linalg.norm(t.points_m[:, :2], axis=1).max()) for t in templates)
    assert radius_m(TrackingConfig().k_search_radius) > reach_m
    assert radius_m(0.01) == pytest.approx(reach_m)


def test_a_tentative_track_is_searched_beside_a_held_one(world) -> None:
    cfg, templates, _, _ = world
    search = GuidedSearch(
        templates,
        cfg,
        TrackingConfig(guided_search=True, full_search_every_frames=3, whole_search_lag_frames=0),
    )
    truck = TrackInput("truck6x6", np.array([5.0, -8.0, 0.0]), 0.5)
    tank = TrackInput("t72", np.array([17.6, 11.8, 0.0]), 0.9)
    for k in (1, 2):
        search.tracker.update([truck], k * SCENE_S)  # the truck's track is confirmed
    nothing = search(np.zeros((0, 3)), seed=0, stamp_ns=3 * SCENE_S, frame_seq=3)  # whole, empty
    assert nothing.stats["search"] == "whole" and not nothing.detections
    search.tracker.update([truck, tank], 4 * SCENE_S)  # the tank seen once: a tentative track
    regions = search.regions(4)
    assert regions is not None and len(regions) == 2
    centres = sorted(tuple(np.round(r.centre_m, 1)) for r in regions)
    assert centres == [(5.0, -8.0), (17.6, 11.8)]


def test_a_guided_scene_lays_at_a_place_only_the_classes_held_there(world) -> None:
    cfg, templates, scene, tank_m = world
    truck_m = TRUCK_SHIFT_M  # the truck stands at its scene's origin with heading 0.2 rad
    for per_place in (True, False):
        tracking = TrackingConfig(
            guided_search=True, full_search_every_frames=3, guided_place_classes=per_place
        )
        search = GuidedSearch(templates, cfg, tracking)
        for k in (1, 2):  # both confirmed, each with a known heading
            search.tracker.update(
                [
                    TrackInput("t72", tank_m, yaw_rad=0.7, score=0.9),
                    TrackInput("truck6x6", truck_m, yaw_rad=0.2, score=0.8),
                ],
                k * SCENE_S,
            )
        search.schedule.searched(whole=True, frame_seq=2)  # frame 3 is guided
        poses, targets = search.places()
        assert len(poses) == 2
        if per_place:
            assert targets == [frozenset({"t72"}), frozenset({"truck6x6"})]
        else:
            assert targets is None
        result = search(scene, seed=0, stamp_ns=3 * SCENE_S, frame_seq=3, viewpoint_m=VIEWPOINT)
        assert result.stats["search"] == 2  # guided: both tracks' cylinders
        laid = {t["target"]: t["hypotheses"] for t in result.stats["templates"]}
        assert laid == ({"t72": 1, "truck6x6": 1} if per_place else {"t72": 2, "truck6x6": 2})
        assert _tank_found(result, tank_m)


def test_a_held_track_s_cylinder_holds_the_classes_held_at_its_place(world) -> None:
    cfg, templates, scene, tank_m = world
    truck_m = TRUCK_SHIFT_M
    reach_m = {t.target: float(np.linalg.norm(t.points_m[:, :2], axis=1).max()) for t in templates}

    def regions(per_class: bool, truck_at: np.ndarray) -> list:
        tracking = TrackingConfig(
            guided_search=True, full_search_every_frames=3, guided_class_cylinders=per_class
        )
        search = GuidedSearch(templates, cfg, tracking)
        for k in (1, 2):
            search.tracker.update(
                [
                    TrackInput("t72", tank_m, yaw_rad=0.7, score=0.9),
                    TrackInput("truck6x6", truck_at, yaw_rad=0.2, score=0.8),
                ],
                k * SCENE_S,
            )
        search.schedule.searched(whole=True, frame_seq=2)
        found = search(scene, seed=0, stamp_ns=3 * SCENE_S, frame_seq=3, viewpoint_m=VIEWPOINT)
        assert found.stats["search"] == 2 and _tank_found(found, tank_m)
        return search.regions(4) or [], search.radius_m

    (tank, truck), largest_m = regions(True, truck_m)
    # each cylinder is its own class's: never less than that template reaches, at most the largest
    assert reach_m["t72"] <= tank.radius_m <= largest_m
    assert reach_m["truck6x6"] <= truck.radius_m <= largest_m
    assert tank.radius_m != pytest.approx(truck.radius_m)
    # without the rule every cylinder is the largest template's
    (tank_, truck_), _ = regions(False, truck_m)
    assert tank_.radius_m == truck_.radius_m == pytest.approx(largest_m)
    # two classes held at one place: its cylinder holds the larger of them
    (tank2, truck2), _ = regions(True, tank_m + np.array([3.0, 0.0, 0.0]))
    assert tank2.radius_m == truck2.radius_m == pytest.approx(max(tank.radius_m, truck.radius_m))


def _lagged_flight(search: GuidedSearch, scene: np.ndarray, frames: range) -> list:
    return [
        search(scene, seed=k, stamp_ns=k * SCENE_S, frame_seq=k, viewpoint_m=VIEWPOINT)
        for k in frames
    ]


def _answers(results: list) -> list:
    return [[d.to_dict() for d in r.detections] for r in results]


def _flight_holding_the_truck(world, tracking: TrackingConfig, lane, frames: range) -> list:
    """A lagged flight over `world`'s scene with the truck's track held from its start."""
    cfg, templates, scene, _ = world
    search = GuidedSearch(templates, cfg, tracking, lane)
    _hold_the_truck(search)
    return _lagged_flight(search, scene, frames)


def _hold_the_truck(search: GuidedSearch) -> None:
    """The truck's track held before the flight's first scene (seen twice: confirmed)."""
    truck = TrackInput("truck6x6", TRUCK_SHIFT_M, yaw_rad=0.2, score=0.8)
    for stamp_ns in (0, SCENE_S // 2):
        search.tracker.update([truck], stamp_ns)


def _tank_found_one(detection, position_m) -> bool:
    return (
        detection.target == "t72"
        and np.linalg.norm(detection.T_world_target[:3, 3] - position_m) < 2.0
    )


def test_a_lagged_whole_search_joins_the_scene_its_lag_names(world) -> None:
    """With whole_search_lag_frames, while a track is held the scene that starts a whole search is
    answered as a guided one; the whole search's detections join the scene `lag` frames later (here
    the tank's, which no track held)."""
    cfg, templates, scene, tank_m = world
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=6, whole_search_lag_frames=2
    )
    search = GuidedSearch(templates, cfg, tracking)
    _hold_the_truck(search)
    results = _lagged_flight(search, scene, range(1, 10))
    found = [_tank_found(r, tank_m) for r in results]
    joined = [r.stats.get("joined_whole_search_of_frame") for r in results]
    handed_over = [r.stats.get("whole_search_handed_over", False) for r in results]
    # frames 1 and 7 (six frames on) are due a whole search: handed over, answered at the truck's place
    assert handed_over == [True, False, False, False, False, False, True, False, False]
    assert results[0].stats["search"] == 1 and results[0].stats["searched_points"] < len(scene)
    assert not found[0] and not found[1]
    # frame 3 is given the tank by frame 1's search; the tank is confirmed where it stands after
    assert joined == [None, None, 1, None, None, None, None, None, 7], joined
    assert found[2] and results[2].stats["late_detections"] >= 1
    assert all(found[2:]), found
    # a late detection at a place the scene's own search found is not given twice
    assert results[8].stats["late_detections"] == 0
    assert all(sum(_tank_found_one(d, tank_m) for d in r.detections) <= 1 for r in results)


def test_a_lagged_flight_answers_its_own_whole_scenes_while_no_track_is_held(world) -> None:
    """Until a track is held every scene is answered by its own search, as without the lag: a whole
    one, or the tentative tracks tried with every template (try_tentative_first): a look-alike's
    template may win a target's place in one whole search and lose it in the next, which a guided
    scene, laying only the classes held there, would not give it."""
    cfg, templates, scene, tank_m = world
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=6, whole_search_lag_frames=2
    )
    results = _lagged_flight(GuidedSearch(templates, cfg, tracking), scene, range(1, 4))
    assert [r.stats["search"] for r in results] == ["whole", "tentative", 1]
    assert not any(r.stats.get("whole_search_handed_over") for r in results)
    assert all(_tank_found(r, tank_m) for r in results)


def test_a_lagged_search_answers_the_same_in_a_process_of_its_own(world) -> None:
    """The lane a whole search runs in changes when it ends, not what any scene is answered."""
    from atr.tracking.lane import ProcessLane

    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=3, whole_search_lag_frames=2
    )
    in_place = _flight_holding_the_truck(world, tracking, None, range(1, 8))
    with ProcessLane() as lane:
        in_worker = _flight_holding_the_truck(world, tracking, lane, range(1, 8))
    assert _answers(in_place) == _answers(in_worker)
    assert in_worker[2].stats["late_detections"] >= 1


class _LateLane:
    """Runs each whole search on a thread and hands its result over `delay_s` later: the worker of a
    machine too slow for the lag."""

    def __init__(self, delay_s: float) -> None:
        self.delay_s = delay_s

    def submit(self, search: WholeSearch) -> Future[RecognitionResult]:
        future: Future[RecognitionResult] = Future()

        def run() -> None:
            try:
                result = search.run()
            except Exception as error:  # noqa: BLE001 - handed to the scene that joins it, as a lane does
                future.set_exception(error)
                return
            time.sleep(self.delay_s)
            future.set_result(result)

        threading.Thread(target=run, daemon=True).start()
        return future

    def close(self) -> None:
        pass


def test_a_scene_that_waits_for_a_lagged_search_says_how_long(world) -> None:
    """The joining scene's stage times hold the wait ("join_wait", in its total too), so the matcher
    can say its lag is too short; a search done in time adds none, and the answers are the same."""
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=6, whole_search_lag_frames=2
    )
    in_place = _flight_holding_the_truck(world, tracking, None, range(1, 4))
    late = _flight_holding_the_truck(world, tracking, _LateLane(delay_s=2.0), range(1, 4))
    assert not any("join_wait" in r.stage_times_ms for r in in_place)
    waits = [r.stage_times_ms.get("join_wait", 0.0) for r in late]
    assert waits[0] == waits[1] == 0.0  # frame 3 joins frame 1's search
    assert waits[2] > 500.0, waits  # most of the two seconds the search was held back
    assert late[2].stage_times_ms["total"] >= waits[2]
    assert _answers(in_place) == _answers(late)


def test_a_lagged_search_of_another_flight_is_dropped(world) -> None:
    """A replay starting at frame 1 again while a whole search of frame 5 waits: the search is dropped
    (it would otherwise join frame 9 of the new flight, and hold the lane until then)."""
    cfg, templates, scene, tank_m = world
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=20, whole_search_lag_frames=4
    )
    search = GuidedSearch(templates, cfg, tracking)
    _hold_the_truck(search)
    first = _lagged_flight(search, scene, range(5, 6))  # frame 5's whole search waits for frame 9
    assert first[0].stats["whole_search_handed_over"]
    again = search(scene, seed=1, stamp_ns=SCENE_S, frame_seq=1, viewpoint_m=VIEWPOINT)
    assert again.stats["whole_search_handed_over"]  # its own, for frame 5 of this flight
    assert "joined_whole_search_of_frame" not in again.stats
    later = _lagged_flight(search, scene, range(2, 6))
    assert [r.stats.get("joined_whole_search_of_frame") for r in later] == [None, None, None, 1]
    assert all(_tank_found(r, tank_m) for r in later)


def test_a_joined_whole_search_decides_the_class_of_a_place_it_shares(world) -> None:
    """At a place the scene found too, the scene's fit stays when the classes agree; when they do not,
    the whole search's class wins (it contested the place with every template); elsewhere its
    detections are added."""
    from atr.recognition import Detection

    cfg, templates, _, _ = world
    search = GuidedSearch(templates, cfg, TrackingConfig(whole_search_lag_frames=2))

    def at(target: str, x_m: float, score: float) -> Detection:
        T = np.eye(4)
        T[0, 3] = x_m
        return Detection(target, DESC, T, score, 0.9, 50)

    own = [at("t72", 0.0, 0.9), at("truck6x6", 30.0, 0.8)]
    late = [at("t72", 0.4, 0.95), at("t72", 30.5, 0.7), at("truck6x6", 60.0, 0.6)]
    joined, kept = search._joined(own, late)
    assert kept == 2
    assert [(d.target, d.T_world_target[0, 3]) for d in joined] == [
        ("t72", 0.0),  # the scene's own fit: the same class
        ("t72", 30.5),  # the whole search's class at the truck's place
        ("truck6x6", 60.0),  # a place only the whole search saw
    ]


def test_a_lane_whose_worker_died_answers_nothing_late_and_starts_again(world) -> None:
    """The worker killed with a search in hand: the scene that search joins keeps its own answer, and
    the next whole search starts a new worker and joins as usual."""
    import os
    import signal

    from atr.tracking.lane import ProcessLane

    cfg, templates, scene, tank_m = world
    tracking = TrackingConfig(
        guided_search=True, full_search_every_frames=6, whole_search_lag_frames=2
    )
    with ProcessLane() as lane:
        worker = lane.warm(cfg).result()
        search = GuidedSearch(templates, cfg, tracking, lane)
        _hold_the_truck(search)
        first = _lagged_flight(search, scene, range(1, 2))  # frame 1's search goes to the worker
        assert first[0].stats["whole_search_handed_over"]
        os.kill(worker, signal.SIGKILL)
        rest = _lagged_flight(search, scene, range(2, 10))
    joined = [r.stats.get("joined_whole_search_of_frame") for r in rest]
    assert joined == [None, 1, None, None, None, None, None, 7]
    assert rest[1].stats["late_detections"] == 0  # frame 1's search died with its worker
    assert rest[5].stats["whole_search_handed_over"]  # frame 7's, to a new worker
    assert _tank_found(rest[7], tank_m)
