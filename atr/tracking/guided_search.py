"""Track-guided search (ours, not the paper's): once a target is held, confirm it where it stands.

A UAV orbiting a target sees it in dozens of consecutive scenes, and a parked vehicle does not move between
them. So once the matcher's own tracker holds a track (confirmed, or lost for a few scenes), the scenes
between two whole-cloud searches only confirm: the cloud is cut to a vertical cylinder around each live
track, and the templates of the classes held at each track's place (``tracking.guided_place_classes``)
are laid at its fused pose and refined by ICP (``atr.recognition.verify_places``), with no description,
matching, grouping or RANSAC; acceptance and the place competition are the whole search's, so a place
still goes to the template that explains it best among those a whole search gave it to. The whole cloud
is searched once every ``tracking.full_search_every_frames`` camera frames and whenever no track is held
(``SearchSchedule``), so a target that appears, or one a false track hid, is found there; a whole search
also lays every template at each live track's pose (``tracking.guided_whole_lays_all``), so a place a
look-alike's template was given goes back to the template that explains it best. The dense SfM step of
a guided scene matches only the cylinders' image windows, each in its own band of disparities
(``tracking.guided_sfm``, ``atr.sfm.dense``). With ``tracking.whole_search_lag_frames`` a whole search
that falls due while a track is held runs beside the next scenes (``atr.tracking.lane``) and its
detections join a scene that many frames later; the scene that started it is answered as a guided one.

The cylinder's radius is ``tracking.k_search_radius`` x the largest footprint (length + width) of the
templates laid at the track's place (``tracking.guided_class_cylinders``), and never less than they
reach from their origin: a vehicle standing at the track's place is inside it at any heading, and so is
some ground around it, which ground removal needs. The tracker is the tracker service's own object
(``atr.tracking.Tracker``) fed with the matcher's detections, so the guidance is deterministic: the
same clouds in the same order give the same searches. A restarted matcher starts with no track and
searches whole clouds until it holds one again.

Before any track is confirmed (a flight's start) a whole search that falls due first tries the tentative
tracks where they stand (``tracking.try_tentative_first``): each one's own class laid at its pose, then,
if each is accepted, every template, the place competition deciding; when each track's own class wins
its place again the scene is answered so and the whole search is skipped, so that the second scene of a
flight is not a second whole search.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

import numpy as np

from atr.errors import AtrError, InputError
from atr.recognition import (
    Detection,
    RecognitionConfig,
    RecognitionResult,
    Template,
    recognize,
    same_place,
    verify_places,
)
from atr.recognition.attention import largest_footprint_m
from atr.recognition.scene import validated_cloud
from atr.recognition.template import model_extent_m
from atr.regions import SearchRegion, points_in_regions
from atr.tracking.config import TrackingConfig
from atr.tracking.lane import InPlaceLane, WholeSearch, WholeSearchLane
from atr.tracking.tracker import Track, Tracker, TrackInput


def _cylinder_around(track: Track, radius_m: float, low_m: float, high_m: float) -> SearchRegion:
    """A vertical cylinder about a track's position, its heights relative to the track's."""
    z_m = float(track.position_m[2])
    return SearchRegion(track.position_m[:2].copy(), radius_m, z_m + low_m, z_m + high_m)


def _add_stage_times(result: RecognitionResult, other: RecognitionResult) -> None:
    """Count another search's stage times in a result's: both ran for its scene."""
    for stage, ms in other.stage_times_ms.items():
        result.stage_times_ms[stage] = result.stage_times_ms.get(stage, 0.0) + ms


class SearchSchedule:
    """Which scenes are searched whole: the first, the first one ``full_search_every_frames`` camera frames
    or more after the last whole one, and every scene while no track is held. Kept by whoever decides
    first: the matcher in process (``GuidedSearch``), or the sfm service, which matches a pair before the
    matcher sees it and tells it in the cloud where it looked.

    The period counts camera frames (a scene's latest frame number), not scenes: the orbit turns by the
    same angle per frame at every range, so a whole search comes at the same part of the orbit whether
    every pair is a scene (a flight) or every fifth is (``atr eval --every 5``), and the evaluation's
    sampled flights search whole where the flight would.
    """

    def __init__(self, full_search_every_frames: int) -> None:
        self.full_search_every_frames = full_search_every_frames
        self._last_whole: int | None = None  # frame number of the last whole search

    def regions(
        self, held: Sequence[SearchRegion] | None, frame_seq: int
    ) -> list[SearchRegion] | None:
        """Where the scene of this frame is searched given the held tracks' regions, or None for the
        whole scene.
        """
        last = self._last_whole
        if not held or last is None or not 0 <= frame_seq - last < self.full_search_every_frames:
            return None
        return list(held)

    def searched(self, *, whole: bool, frame_seq: int) -> None:
        """Note that the scene of this frame was searched whole or only in regions."""
        if whole:
            self._last_whole = frame_seq

    def reset(self) -> None:
        """Start again: the next scene is searched whole."""
        self._last_whole = None


@dataclass
class _PendingSearch:
    """A whole search handed to the lane: the frame that started it and the one its detections join."""

    frame_seq: int
    join_frame_seq: int
    result: Future[RecognitionResult]


class GuidedSearch:
    """The matcher with track-guided search, scene by scene: a whole search (``recognize``), or a
    confirmation of the live tracks' poses on their neighbourhoods (``verify_places``). With
    ``tracking.guided_search`` off it is ``recognize`` itself.

    Attributes:
        tracker: the tracks the matcher's own detections make (not published; the tracker service
            keeps the tracks users see).

    """

    def __init__(
        self,
        templates: Sequence[Template],
        recognition: RecognitionConfig,
        tracking: TrackingConfig,
        lane: WholeSearchLane | None = None,
    ) -> None:
        self.templates = list(templates)
        self.recognition = recognition
        self.tracking = tracking
        self.tracker = Tracker(tracking)
        # each class's cylinder: its radius and the heights it spans from the track's position
        self._cylinders: dict[str, tuple[float, float, float]] = {}
        for t in self.templates:
            if len(t.points_m):
                radius_m, low_m, high_m = self._cylinder_of(t.points_m, tracking.k_search_radius)
                if t.target in self._cylinders:
                    r, lo, hi = self._cylinders[t.target]
                    radius_m, low_m, high_m = max(r, radius_m), min(lo, low_m), max(hi, high_m)
                self._cylinders[t.target] = (radius_m, low_m, high_m)
        cylinders = list(self._cylinders.values())
        self.radius_m = max((c[0] for c in cylinders), default=0.0)
        self.z_span_m = (
            (min(c[1] for c in cylinders), max(c[2] for c in cylinders))
            if cylinders
            else (0.0, 0.0)
        )
        self.schedule = SearchSchedule(tracking.full_search_every_frames)
        # whole searches that answer late (whole_search_lag_frames): where they run, the one running
        self._lagged = tracking.guided_search and tracking.whole_search_lag_frames > 0
        self.lane: WholeSearchLane = lane if lane is not None else InPlaceLane()
        self._pending: _PendingSearch | None = None
        self._extent_m: dict[str, float] = {}  # each class's largest extent: one place's reach
        for t in self.templates:
            self._extent_m[t.target] = max(self._extent_m.get(t.target, 0.0), model_extent_m(t))
        # each live track's consecutive misses before the latest scene (guided_reacquire_misses)
        self._misses: dict[int, int] = {}
        self._reacquire = False  # a held target went unconfirmed: the next scene is searched whole

    @staticmethod
    def _cylinder_of(points_m: np.ndarray, k_search_radius: float) -> tuple[float, float, float]:
        """A template's search cylinder about its origin: radius, lowest and highest height, metres.
        The radius is never less than the template reaches from its origin (the track's place) at any
        heading: a CAD model's origin need not be its footprint's centre.
        """
        reach_m = float(np.linalg.norm(points_m[:, :2], axis=1).max())
        radius_m = max(k_search_radius * largest_footprint_m(points_m), reach_m)
        return radius_m, float(points_m[:, 2].min()), float(points_m[:, 2].max())

    def regions(self, frame_seq: int) -> list[SearchRegion] | None:
        """Where the scene of this frame is searched, or None for the whole cloud (``SearchSchedule``)."""
        return self.schedule.regions(self.held_regions(), frame_seq)

    def held_regions(self) -> list[SearchRegion] | None:
        """The cylinders around the live tracks while one is held, else None: what the matcher publishes
        for the sfm service's own schedule. None too after a scene in which a confirmed track went
        unconfirmed (``tracking.guided_reacquire_misses``).

        A track is held when confirmed, or lost for a few scenes; then every live track is searched,
        tentative ones too: a target a whole search saw once must get the scenes that confirm it, or a
        held confuser's neighbourhood would be all the matcher looks at until the next whole search.
        """
        tracks = self.tracker.tracks
        if not self.tracking.guided_search or all(t.state == "tentative" for t in tracks):
            return None
        if self._reacquire:  # look everywhere once for a target the latest scene lost
            return None
        regions = []
        for track in tracks:
            radius_m, (low, high) = self.radius_m, self.z_span_m
            if self.tracking.guided_place_classes and self.tracking.guided_class_cylinders:
                # only the classes held at the place are laid there: the cylinder need hold only them
                cylinders = [
                    self._cylinders[c] for c in self._classes_at(track) if c in self._cylinders
                ]
                if cylinders:
                    radius_m = max(c[0] for c in cylinders)
                    low, high = min(c[1] for c in cylinders), max(c[2] for c in cylinders)
            regions.append(_cylinder_around(track, radius_m, low, high))
        return regions

    def _classes_at(self, track: Track) -> frozenset[str]:
        """The classes of the live tracks that stand at a track's place (within the search radius)."""
        return frozenset(
            other.target
            for other in self.tracker.tracks
            if np.linalg.norm(other.position_m[:2] - track.position_m[:2]) <= self.radius_m
        )

    def places(self) -> tuple[list[np.ndarray], list[frozenset[str]] | None]:
        """The poses a guided scene confirms and the templates laid at each: every live track's fused
        pose, turned by 180 degrees too where its heading is known only modulo 180 degrees (or not at
        all). With ``tracking.guided_place_classes`` a pose gets the templates of the classes whose
        tracks stand at its place (within the search radius of it), else every template (None).
        """
        poses, targets = [], []
        for track in self.tracker.tracks:
            turns = self._turns(track)
            poses += turns
            targets += [self._classes_at(track)] * len(turns)
        return poses, targets if self.tracking.guided_place_classes else None

    @staticmethod
    def _turns(track: Track) -> list[np.ndarray]:
        """A track's fused pose, and turned by 180 degrees while its heading is unsure."""
        T = track.T_world_target
        if not track.yaw_ambiguous and np.isfinite(track.yaw_var):
            return [T]
        flipped = T.copy()
        flipped[:2, :2] = -T[:2, :2]
        return [T, flipped]

    def __call__(
        self,
        scene_points_m: np.ndarray,
        *,
        seed: int,
        stamp_ns: int,
        frame_seq: int,
        viewpoint_m: np.ndarray | None = None,
        scene_sigma_m: np.ndarray | None = None,
        cloud_regions: Sequence[SearchRegion] | None = None,
    ) -> RecognitionResult:
        """Recognise the templates in one scene: a whole search, or where ``regions`` says the tracks'
        poses are confirmed.

        Args as ``atr.recognition.recognize``, and ``stamp_ns``: the scene's stamp (the tracker ages its
        tracks by the scenes between stamps); ``frame_seq``: the number of the scene's latest camera
        frame (the schedule of whole searches counts frames); ``cloud_regions``: where the SfM step
        matched the cloud when it decided (the sfm service keeps its own ``SearchSchedule``): a cloud
        matched in regions is searched in them, whatever the matcher holds, so that its search does
        not depend on when guidance arrived; one matched whole (empty), or None, is searched where
        ``regions`` says. In lock-step the two schedules agree; at the camera's pace sfm matches pairs
        whole until the matcher's first guidance reaches it, and the matcher, holding a track by then,
        confirms it in those clouds rather than searching each whole.

        Returns:
            ``recognize``'s or ``verify_places``'s result (``recognize``'s on the regions' points when a
            cloud matched in regions meets a matcher that holds no track); its stats gain "search":
            "whole" or the number of regions, and "searched_points": the points it was given. With
            ``whole_search_lag_frames``: "whole_search_handed_over" when the scene started a whole
            search in the lane, and in the scene it joins "joined_whole_search_of_frame" and
            "late_detections" (how many of its detections the answer took: ``_joined``).

        Raises:
            As ``recognize`` (the input is checked there). A stamp not after the previous scene's does
            not raise: the guidance starts again from no track, so the next scene is searched whole.

        """
        # a cloud matched in regions is searched there; one matched whole (or not said) where the
        # schedule says: at the camera's pace sfm matches pairs whole until the guidance reaches it
        regions = list(cloud_regions) if cloud_regions else self.regions(frame_seq)
        late, joined, waited_ms = self._join(frame_seq) if self._lagged else ([], None, 0.0)
        handed_over = False
        if regions is None and self._lagged and (live := self.held_regions()) is not None:
            # a track is held: the whole search runs beside the next scenes (unless the one before
            # still does), and this scene is guided
            handed_over = self._hand_over(
                scene_points_m, seed, frame_seq, viewpoint_m, scene_sigma_m
            )
            regions = live
        points, sigma = np.asarray(scene_points_m), scene_sigma_m
        well_formed = points.ndim == 2 and points.shape[1] == 3
        if not well_formed:
            regions = None  # recognize, searching whole, names what is wrong with the cloud
        if regions is not None:
            inside = points_in_regions(points.astype(np.float64), regions)
            points = points[inside]
            if sigma is not None and np.shape(sigma) == (len(inside),):
                sigma = np.asarray(sigma)[inside]
        poses, targets = self.places() if well_formed else ([], None)
        # before any track is confirmed, a whole search is first spared by trying the tentative ones
        tried: RecognitionResult | None = None
        if regions is None and well_formed and self._holds_only_tentative():
            tried = self._try_tentative(points, sigma, seed, viewpoint_m)
        won = tried is not None and tried.stats["tentative_won"]
        if won:
            result = tried
        elif regions is not None and poses:
            result = verify_places(
                points,
                self.templates,
                self.recognition,
                poses,
                seed=seed,
                viewpoint_m=viewpoint_m,
                scene_sigma_m=sigma,
                targets_per_place=targets,
            )
        else:
            # A whole search, which also lays every template at the held places; or a cloud matched in
            # regions meeting a matcher that holds no track (a restarted one, whose sfm still follows
            # the guidance it had): every template searches the regions, so their targets are found again.
            t = self.tracking
            lays_all = regions is None and t.guided_search and t.guided_whole_lays_all
            result = recognize(
                points,
                self.templates,
                self.recognition,
                seed=seed,
                viewpoint_m=viewpoint_m,
                scene_sigma_m=sigma,
                places_T_world_target=poses if lays_all else [],
            )
        if won:
            result.stats["search"] = "tentative"
        else:
            result.stats["search"] = "whole" if regions is None else len(regions)
            result.stats["searched_points"] = len(points)
        if tried is not None and not won:
            _add_stage_times(result, tried)  # the failed try's time is the scene's too
            result.stats["tentative_won"] = False
            result.stats["tentative_templates"] = tried.stats["tentative_templates"]
        if handed_over:
            result.stats["whole_search_handed_over"] = True
            whole_search = self._pending.result if self._pending is not None else None
            in_place = isinstance(self.lane, InPlaceLane) and whole_search is not None
            if in_place and not whole_search.exception():
                # run in place (the evaluation): its time is this scene's, as without the lag
                _add_stage_times(result, whole_search.result())
        if joined is not None:
            result.detections, kept = self._joined(result.detections, late)
            result.stats["late_detections"] = kept
            result.stats["joined_whole_search_of_frame"] = joined
        if waited_ms > 0.0:
            # the lane's search was still running when its joining scene came: the lag is too short
            # for this machine at this frame rate (a time, so in the stage times, never in the stats)
            result.stage_times_ms["join_wait"] = waited_ms
            result.stage_times_ms["total"] = result.stage_times_ms.get("total", 0.0) + waited_ms
        if self.tracking.guided_search:
            whole = regions is None or handed_over
            self._observe(result, stamp_ns, frame_seq, viewpoint_m, whole=whole)
        return result

    def _holds_only_tentative(self) -> bool:
        """Whether a whole search due now may first try the tentative tracks (try_tentative_first)."""
        tracks = self.tracker.tracks
        t = self.tracking
        return (
            t.guided_search
            and t.try_tentative_first
            and bool(tracks)
            and all(track.state == "tentative" for track in tracks)
        )

    def _try_tentative(
        self,
        points: np.ndarray,
        sigma: np.ndarray | None,
        seed: int,
        viewpoint_m: np.ndarray | None,
    ) -> RecognitionResult:
        """The tentative tracks tried where they stand, in cylinders the largest template's size (every
        template may be laid there). Its stats say whether each
        track's own class won its place again ("tentative_won") and how many points it searched.

        Each track's own class is laid alone first: a template's fit is accepted or not whatever else
        is laid beside it, so when a track's own class is not accepted at its place it cannot win it,
        and the try stops there at the cost of one template's ICP, not every template's (a tentative
        track whose try fails is most often a single false fit: at 0 degrees, many a flight).
        """
        # a cloud the whole search would refuse is refused here, whatever lies outside the cylinders
        points, sigma = validated_cloud(points, sigma, self.recognition)
        tracks = self.tracker.tracks
        cylinders = [_cylinder_around(t, self.radius_m, *self.z_span_m) for t in tracks]
        inside = points_in_regions(points, cylinders)
        poses = [(T, t.target) for t in tracks for T in self._turns(t)]

        def laid(targets_per_place: list[set[str]] | None) -> RecognitionResult:
            result = verify_places(
                points[inside],
                self.templates,
                self.recognition,
                [T for T, _ in poses],
                seed=seed,
                viewpoint_m=viewpoint_m,
                scene_sigma_m=None if sigma is None else sigma[inside],
                targets_per_place=targets_per_place,
            )
            result.stats["tentative_won"] = all(
                any(d.target == t.target and self._at_track(d, t) for d in result.detections)
                for t in tracks
            )
            result.stats["searched_points"] = int(inside.sum())
            laid_classes = set().union(*targets_per_place) if targets_per_place else None
            result.stats["tentative_templates"] = sum(
                1 for tpl in self.templates if laid_classes is None or tpl.target in laid_classes
            )
            return result

        alone = laid([{target} for _, target in poses])
        if not alone.stats["tentative_won"]:
            return alone
        result = laid(None)
        _add_stage_times(result, alone)  # both are the try's time
        return result

    def _at_track(self, detection: Detection, track: Track) -> bool:
        """Whether a detection stands at a track's place, as the place competition judges one place."""
        return self._one_place(
            detection.T_world_target[:3, 3], detection.target, track.position_m, track.target
        )

    def _hand_over(
        self,
        scene_points_m: np.ndarray,
        seed: int,
        frame_seq: int,
        viewpoint_m: np.ndarray | None,
        scene_sigma_m: np.ndarray | None,
    ) -> bool:
        """Hand a whole search to the lane, its detections to join the scene
        ``whole_search_lag_frames`` frames on; False when the one before has not joined yet (a
        period shorter than the lag). Raises InputError, as ``recognize`` does, for a bad cloud.
        """
        if self._pending is not None:
            return False
        points, sigma = validated_cloud(scene_points_m, scene_sigma_m, self.recognition)
        lays_all = self.tracking.guided_whole_lays_all
        options = {
            "seed": seed,
            "viewpoint_m": viewpoint_m,
            "scene_sigma_m": sigma,
            "places_T_world_target": self.places()[0] if lays_all else [],
        }
        future = self.lane.submit(WholeSearch(self.templates, self.recognition, points, options))
        lag = self.tracking.whole_search_lag_frames
        self._pending = _PendingSearch(frame_seq, frame_seq + lag, future)
        return True

    def _join(self, frame_seq: int) -> tuple[list[Detection], int | None, float]:
        """The detections of the whole search in the lane when this frame is the one they join (waiting
        for it if it still runs), the frame it started at, and how long this scene waited for it (ms);
        else none. A search started at a later frame than this one (another flight, a replay) is dropped.
        """
        pending = self._pending
        if pending is None or frame_seq < pending.join_frame_seq:
            if pending is not None and frame_seq < pending.frame_seq:
                pending.result.cancel()
                self._pending = None
            return [], None, 0.0
        self._pending = None
        started = None if pending.result.done() else time.perf_counter()
        try:
            detections = pending.result.result().detections
        except (AtrError, BrokenProcessPool):
            # a cloud recognize refused, or a worker that died: the scene keeps its own answer
            detections = []
        waited_ms = 0.0 if started is None else 1e3 * (time.perf_counter() - started)
        return detections, pending.frame_seq, waited_ms

    def _joined(self, own: list[Detection], late: list[Detection]) -> tuple[list[Detection], int]:
        """A scene's detections with a lagged whole search's joined, and how many of those were kept.

        A vehicle parked where the whole search found it is there still. At a place this scene found
        too, the scene keeps its own fit when the classes agree (it is the newer view); when they do
        not, the whole search's class wins: it laid every template there and searched with the
        descriptors, where this scene laid only the classes held at the place, so a look-alike that
        holds a target's place would otherwise keep it (docs/tracking.md, "Whole searches that answer
        late").
        """
        kept = [d for d in late if not any(self._same_place(d, o) for o in own)]
        replaced = [
            d for d in late if any(self._same_place(d, o) and d.target != o.target for o in own)
        ]
        own = [o for o in own if not any(self._same_place(d, o) for d in replaced)]
        joined = own + kept + replaced
        return sorted(joined, key=lambda d: -d.score), len(kept) + len(replaced)

    def _same_place(self, a: Detection, b: Detection) -> bool:
        """Whether two detections are one place, as the place competition judges it."""
        return self._one_place(a.T_world_target[:3, 3], a.target, b.T_world_target[:3, 3], b.target)

    def _one_place(
        self, position_a_m: np.ndarray, target_a: str, position_b_m: np.ndarray, target_b: str
    ) -> bool:
        """Whether two vehicles' positions are one place, the larger class's extent deciding."""
        extent_m = max(self._extent_m.get(target_a, 0.0), self._extent_m.get(target_b, 0.0))
        return same_place(position_a_m, position_b_m, extent_m, self.recognition.nms_m)

    def _observe(
        self,
        result: RecognitionResult,
        stamp_ns: int,
        frame_seq: int,
        viewpoint_m: np.ndarray | None,
        *,
        whole: bool,
    ) -> None:
        inputs = [
            TrackInput.from_pose(d.target, d.T_world_target, d.score, viewpoint_m)
            for d in result.detections
        ]
        try:
            self.tracker.update(inputs, stamp_ns)
        except InputError:  # scenes out of order: guide again from scratch
            self.tracker = Tracker(self.tracking)
            self.schedule.reset()
            self._misses, self._reacquire = {}, False
            return
        self.schedule.searched(whole=whole, frame_seq=frame_seq)
        # a confirmed track that has just gone unconfirmed for k scenes in a row: look everywhere once
        k = self.tracking.guided_reacquire_misses
        tracks = self.tracker.tracks
        self._reacquire = k > 0 and any(
            t.state == "lost" and self._misses.get(t.id, 0) < k <= t.misses for t in tracks
        )
        self._misses = {t.id: t.misses for t in tracks}
