"""Tracks: per-scene detections associated across scenes in the world frame, confirmed, fused and aged.

The filter is a few lines of numpy rather than filterpy: the target is a ground vehicle whose state is its
position and heading, nearly constant between scenes, so a constant-position Kalman filter (predict: add the
random walk; update: the information-weighted mean) is all there is; heading needs a wrapped innovation and
the 180-degree ambiguity, which filterpy's KalmanFilter does not handle anyway. Association is one
`scipy.optimize.linear_sum_assignment` per scene over the gated Mahalanobis costs (one target per track).
The fused position is, by default, the geometric median of the track's latest detections rather than the
filter's mean: a fit that slid a metre on a half-hidden vehicle moves a median by little and a mean by its
share (`TrackingConfig.fuse_median`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.optimize import linear_sum_assignment

from atr.errors import InputError
from atr.tracking.config import TrackingConfig

TrackState = Literal["tentative", "confirmed", "lost"]
_INFEASIBLE = 1e12


@dataclass(frozen=True)
class TrackInput:
    """One detection as the tracker sees it.

    Attributes:
        target: class (template name) of the detection, e.g. t72.
        position_m: (3,) position of the target in the world frame, metres.
        yaw_rad: heading of the target in the world frame about z, radians; None when the source gives
            positions only (the heading gate and heading fusion are then skipped).
        score: the matcher's score of the detection (its class evidence with
            ``TrackingConfig.class_votes``).
        viewpoint_m: (3,) sensor position of the scene the detection came from, world frame, metres;
            None when unknown. The fused median weighs the detection's offset along its horizontal
            line of sight by ``TrackingConfig.fuse_line_of_sight_weight``: an SfM cloud is least
            sure in depth.

    """

    target: str
    position_m: np.ndarray
    yaw_rad: float | None = None
    score: float = 1.0
    viewpoint_m: np.ndarray | None = None

    @classmethod
    def from_pose(
        cls,
        target: str,
        T_world_target: np.ndarray,
        score: float = 1.0,
        viewpoint_m: np.ndarray | None = None,
    ) -> TrackInput:
        """A detection from its 4x4 world-from-target pose (heading from the x axis's direction)."""
        T = np.asarray(T_world_target, np.float64)
        yaw = float(math.atan2(T[1, 0], T[0, 0]))
        viewpoint = None if viewpoint_m is None else np.asarray(viewpoint_m, np.float64)
        return cls(target, T[:3, 3].copy(), yaw, float(score), viewpoint)

    def line_of_sight(self) -> np.ndarray:
        """(3,) horizontal unit vector from the viewpoint to the detection; zeros when the viewpoint
        is unknown or straight above it.
        """
        if self.viewpoint_m is None:
            return np.zeros(3)
        ray = np.asarray(self.position_m, np.float64) - self.viewpoint_m
        ray[2] = 0.0
        norm = float(np.linalg.norm(ray))
        return ray / norm if norm > 1e-6 else np.zeros(3)


@dataclass
class Track:
    """One target's belief.

    Attributes:
        id: track id, unique within the tracker's life (1, 2, ... in order of creation).
        target: class of the detections it fuses; with ``TrackingConfig.class_votes``, the class with
            the most evidence so far (the first to reach it on a tie).
        state: "tentative" (not yet M hits in N scenes), "confirmed" (seen this scene, confirmed), or
            "lost" (confirmed, missed the latest scene; deleted after `delete_after_misses`, or
            `miss_patience_per_hit` x hits if more).
        position_m: (3,) fused position in the world frame, metres: the filter's mean, or with
            ``TrackingConfig.fuse_median`` the geometric median of `places_m`.
        P_position: (3, 3) its covariance, square metres (the filter's, also under ``fuse_median``).
        yaw_rad: fused heading, radians in [-pi, pi) (0 and yaw_var = inf while no detection gave one).
        yaw_var: its variance, square radians.
        yaw_ambiguous: heading is known only modulo 180 degrees (the detections showed both ends).
        hits: detections fused.
        first_seen_ns: stamp of the first detection.
        last_seen_ns: stamp of the latest detection.
        supporting_stamps_ns: stamps of the latest supporting detections, oldest first.
        places_m: positions of the latest ``TrackingConfig.fuse_window`` detections fused, oldest first.
        sights: their horizontal lines of sight (``TrackInput.line_of_sight``), the same order.
        class_evidence: with ``TrackingConfig.class_votes``, the summed scores of the detections of
            each class at the track's place.
        class_hits: with ``TrackingConfig.class_votes``, how many detections of each class it had.

    """

    id: int
    target: str
    position_m: np.ndarray
    P_position: np.ndarray
    yaw_rad: float
    yaw_var: float
    first_seen_ns: int
    state: TrackState = "tentative"
    yaw_ambiguous: bool = False
    hits: int = 1
    last_seen_ns: int = 0
    supporting_stamps_ns: list[int] = field(default_factory=list)
    places_m: list[np.ndarray] = field(default_factory=list, repr=False)
    sights: list[np.ndarray] = field(default_factory=list, repr=False)
    class_evidence: dict[str, float] = field(default_factory=dict)
    class_hits: dict[str, int] = field(default_factory=dict)
    _window: list[bool] = field(default_factory=list, repr=False)
    _misses: int = 0
    _flips: int = 0

    @property
    def misses(self) -> int:
        """Consecutive scenes, up to the latest, in which the track was not seen (0: seen in it)."""
        return self._misses

    @property
    def T_world_target(self) -> np.ndarray:
        """(4, 4) world-from-target pose of the fused position and heading (z up, no roll or pitch)."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        T = np.eye(4)
        T[:2, :2] = [[c, -s], [s, c]]
        T[:3, 3] = self.position_m
        return T

    @property
    def covariance(self) -> np.ndarray:
        """(4, 4) covariance of (x, y, z, yaw), square metres and square radians (yaw: pi^2 if unknown)."""
        C = np.zeros((4, 4))
        C[:3, :3] = self.P_position
        C[3, 3] = self.yaw_var if math.isfinite(self.yaw_var) else math.pi**2
        return C


def geometric_median(
    points_m: np.ndarray,
    start_m: np.ndarray | None = None,
    tol_m: float = 1e-4,
    max_iter: int = 50,
    sights: np.ndarray | None = None,
    sight_weight: float = 1.0,
) -> np.ndarray:
    """The point with the least summed distance to `points_m` (N, 3): Weiszfeld's iteration from
    `start_m` (the coordinate-wise median when None) until a step is under `tol_m`. Unlike the
    coordinate-wise median it does not depend on the world axes; a few lines of numpy, as neither numpy
    nor scipy has it. Deterministic: the same points and start give the same point.

    With `sights` (N, 3) unit vectors (or zeros), each point's distance is measured with the part
    along its sight scaled by sqrt(`sight_weight`): the metric (x - p)^T W (x - p), W = I - (1 - w) s s^T,
    and the iteration is the same reweighting with W (each step a 3 x 3 solve).
    """
    y = np.median(points_m, axis=0) if start_m is None else np.asarray(start_m, np.float64)
    # (x - p)^T W (x - p) = |x - p|^2 - k (s . (x - p))^2 with k = 1 - w: no 3 x 3 per point
    k = 0.0 if sights is None else 1.0 - sight_weight
    s = np.zeros_like(points_m) if sights is None else np.asarray(sights, np.float64)
    s_dot_p = np.einsum("ij,ij->i", s, points_m)
    for _ in range(max_iter):
        offsets = points_m - y
        along = s_dot_p - s @ y
        squared = np.einsum("ij,ij->i", offsets, offsets) - k * along * along
        # a point at y would divide by zero; 1 mm keeps its weight finite and large
        inv = 1.0 / np.sqrt(np.maximum(squared, 1e-6))
        # sum_i W_i / d_i and sum_i W_i p_i / d_i
        A = inv.sum() * np.eye(3) - k * (s.T * inv) @ s
        b = inv @ points_m - k * (inv * s_dot_p) @ s
        y_next = np.linalg.solve(A, b)
        if float(np.linalg.norm(y_next - y)) < tol_m:
            return y_next
        y = y_next
    return y


def _wrap(angle: float, period: float = 2 * math.pi) -> float:
    """`angle` wrapped into [-period / 2, period / 2)."""
    return (angle + period / 2) % period - period / 2


class Tracker:
    """Associates, confirms, fuses and ages tracks; one `update` per scene, in stamp order.

    Deterministic: the same detections in the same order give the same tracks (no randomness; ties in
    the assignment resolve by track and detection order).
    """

    def __init__(self, config: TrackingConfig | None = None) -> None:
        self.config = config or TrackingConfig()
        self.tracks: list[Track] = []
        self._next_id = 1
        self._last_stamp_ns: int | None = None
        self._steps_ns: list[int] = []

    # Public interface

    def update(self, detections: Sequence[TrackInput], stamp_ns: int) -> list[Track]:
        """Fold one scene's detections into the tracks.

        Args:
            detections: the scene's detections (any classes), in the matcher's order.
            stamp_ns: the scene's stamp; strictly later than the previous scene's.

        Returns:
            The live tracks after this scene, by id (deleted tracks are gone).

        Raises:
            InputError: a stamp not after the previous one, or a detection with a non-finite or
                malformed position or heading; the tracks are then unchanged.

        """
        self._check(detections, stamp_ns)
        scenes = self._scenes_since(stamp_ns)
        self._expire(scenes)
        self._predict(scenes)
        assigned = self._associate(detections)
        for t, d in assigned.items():
            self._fuse(self.tracks[t], detections[d], stamp_ns)
        hit = {self.tracks[t].id for t in assigned}
        self._spawn_or_vote(detections, set(assigned.values()), hit, stamp_ns)
        self._age(hit, scenes, stamp_ns)
        self._last_stamp_ns = stamp_ns
        return list(self.tracks)

    # Steps

    def _check(self, detections: Sequence[TrackInput], stamp_ns: int) -> None:
        if self._last_stamp_ns is not None and stamp_ns <= self._last_stamp_ns:
            raise InputError(
                f"scene stamp {stamp_ns} ns is not after the previous scene's {self._last_stamp_ns} ns; "
                "the tracker expects scenes in stamp order"
            )
        for i, d in enumerate(detections):
            p = np.asarray(d.position_m, np.float64)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise InputError(
                    f"detection {i} ({d.target}) position {p.tolist()} must be 3 finite metres"
                )
            if d.yaw_rad is not None and not math.isfinite(d.yaw_rad):
                raise InputError(f"detection {i} ({d.target}) heading {d.yaw_rad} must be finite")
            if not (math.isfinite(d.score) and d.score >= 0):
                raise InputError(
                    f"detection {i} ({d.target}) score {d.score} must be finite and >= 0"
                )

    def _scenes_since(self, stamp_ns: int) -> int:
        """Scenes elapsed since the last update: 1, or the span of a gap in units of the usual step."""
        if self._last_stamp_ns is None:
            return 1
        step = stamp_ns - self._last_stamp_ns
        usual = int(np.median(self._steps_ns)) if self._steps_ns else step
        self._steps_ns = [*self._steps_ns[-7:], step]
        return max(1, round(step / usual))

    def _max_misses(self, track: Track) -> int:
        c = self.config
        if track.state == "tentative":  # more misses and it can no longer reach M of N
            return c.confirm_window - c.confirm_hits
        # a track seen often has earned more patience (miss_patience_per_hit)
        return max(c.delete_after_misses, math.floor(c.miss_patience_per_hit * track.hits)) - 1

    def _expire(self, scenes: int) -> None:
        """Delete, before association, the tracks a gap's unseen scenes alone age out."""
        self.tracks = [t for t in self.tracks if t._misses + scenes - 1 <= self._max_misses(t)]

    def _predict(self, scenes: int) -> None:
        c = self.config
        q_m2 = (c.k_process * c.position_sigma_m) ** 2 * scenes
        q_yaw = math.radians(c.yaw_process_deg) ** 2 * scenes
        for track in self.tracks:
            track.P_position = track.P_position + q_m2 * np.eye(3)
            track.yaw_var += q_yaw

    def _near(self, d: TrackInput) -> list[int]:
        """Indices of the tracks not surely outside `d`'s position gate, found without solving:
        r^T S^-1 r >= |r|^2 / trace(S), since S's largest eigenvalue is at most its trace. Most pairs
        are far (clutter across a city), so one numpy pass over all tracks settles them; no track it
        leaves out could pass the gate.
        """
        if not self.tracks:
            return []
        positions_m = np.array([t.position_m for t in self.tracks])
        traces = np.array([t.P_position.trace() for t in self.tracks])
        trace_S = traces + 3 * self.config.position_sigma_m**2
        r = positions_m - np.asarray(d.position_m, np.float64)
        near = np.einsum("ij,ij->i", r, r) <= self.config.k_gate**2 * trace_S
        return np.flatnonzero(near).tolist()

    def _gates(self, track: Track, d: TrackInput) -> tuple[float, float, bool]:
        """(squared position distance in sigmas, squared heading distance in sigmas, whether the
        heading is 180 degrees off the track's within the heading gate).
        """
        c = self.config
        r = np.asarray(d.position_m, np.float64) - track.position_m
        S = track.P_position + c.position_sigma_m**2 * np.eye(3)
        d2 = float(r @ np.linalg.solve(S, r))
        if d.yaw_rad is None or not math.isfinite(track.yaw_var):
            return d2, 0.0, False
        s2 = track.yaw_var + math.radians(c.yaw_sigma_deg) ** 2
        r_yaw = _wrap(d.yaw_rad - track.yaw_rad, math.pi if track.yaw_ambiguous else 2 * math.pi)
        flipped = _wrap(d.yaw_rad - track.yaw_rad + math.pi) ** 2 / s2 <= c.k_heading_gate**2
        return d2, r_yaw**2 / s2, flipped

    def _associate(self, detections: Sequence[TrackInput]) -> dict[int, int]:
        """Track index -> detection index: the cheapest one-to-one pairing within the gates."""
        if not self.tracks or not detections:
            return {}
        c = self.config
        cost = np.full((len(self.tracks), len(detections)), _INFEASIBLE)
        for j, d in enumerate(detections):
            for t in self._near(d):
                track = self.tracks[t]
                if not self._same_class(track, d):
                    continue
                d2, h2, _ = self._gates(track, d)
                if d2 > c.k_gate**2:
                    continue
                if h2 <= c.k_heading_gate**2:
                    cost[t, j] = d2 + h2
                elif c.class_votes:  # one vehicle per place: its heading may be a look-alike's
                    cost[t, j] = d2 + c.k_heading_gate**2
        rows, cols = linear_sum_assignment(cost)
        return {int(t): int(j) for t, j in zip(rows, cols, strict=True) if cost[t, j] < _INFEASIBLE}

    def _same_class(self, track: Track, d: TrackInput) -> bool:
        """Whether a detection may join the track: of its class, or of any with ``class_votes``
        (one vehicle per place: look-alike templates winning it in turn are evidence, not vehicles).
        """
        return self.config.class_votes or d.target == track.target

    def _heading_fits(self, track: Track, d: TrackInput) -> bool:
        """Whether the detection's heading is within the track's heading gate (always, without
        ``class_votes``: association gated it already).
        """
        return (
            not self.config.class_votes or self._gates(track, d)[1] <= self.config.k_heading_gate**2
        )

    def _vote(self, track: Track, d: TrackInput) -> None:
        """Add a detection's score to its class's evidence; the track takes the leading class."""
        if not self.config.class_votes:
            return
        evidence = track.class_evidence
        evidence[d.target] = evidence.get(d.target, 0.0) + float(d.score)
        track.class_hits[d.target] = track.class_hits.get(d.target, 0) + 1
        track.target = max(evidence, key=lambda name: evidence[name])  # first of equals

    def _class_recurs(self, track: Track) -> bool:
        """Whether the track's class was itself detected confirm_hits times (``class_recurs``)."""
        c = self.config
        return not (c.class_votes and c.class_recurs) or (
            track.class_hits.get(track.target, 0) >= c.confirm_hits
        )

    def _fuse(self, track: Track, d: TrackInput, stamp_ns: int, heading: bool = True) -> None:
        """Fold a detection into the track: position always, heading when ``heading`` and it fits."""
        c = self.config
        self._vote(track, d)
        R = c.position_sigma_m**2 * np.eye(3)
        K = track.P_position @ np.linalg.inv(track.P_position + R)
        previous_m = track.position_m
        track.position_m = track.position_m + K @ (np.asarray(d.position_m) - track.position_m)
        track.P_position = (np.eye(3) - K) @ track.P_position
        track.P_position = 0.5 * (track.P_position + track.P_position.T)  # keep it symmetric
        track.places_m = [*track.places_m, np.asarray(d.position_m, np.float64)][-c.fuse_window :]
        track.sights = [*track.sights, d.line_of_sight()][-c.fuse_window :]
        if c.fuse_median and len(track.places_m) >= 3:  # of two points any between is a median
            # from the last fused position: a new place moves the median little, so a few steps do
            track.position_m = geometric_median(
                np.asarray(track.places_m),
                start_m=previous_m,
                sights=np.asarray(track.sights),
                sight_weight=c.fuse_line_of_sight_weight,
            )
        if heading and d.yaw_rad is not None and self._heading_fits(track, d):
            r_yaw = math.radians(c.yaw_sigma_deg) ** 2
            if math.isfinite(track.yaw_var):
                period = math.pi if track.yaw_ambiguous else 2 * math.pi
                gain = track.yaw_var / (track.yaw_var + r_yaw)
                track.yaw_rad = _wrap(
                    track.yaw_rad + gain * _wrap(d.yaw_rad - track.yaw_rad, period)
                )
                track.yaw_var = (1 - gain) * track.yaw_var
            else:
                track.yaw_rad, track.yaw_var = _wrap(d.yaw_rad), r_yaw
        track.hits += 1
        track.last_seen_ns = stamp_ns
        track.supporting_stamps_ns = [*track.supporting_stamps_ns, stamp_ns][-c.supporting_max :]

    def _spawn_or_vote(
        self, detections: Sequence[TrackInput], used: set[int], hit: set[int], stamp_ns: int
    ) -> None:
        """A detection no track took starts a tentative track, unless it sits at a track's place: one
        vehicle per place, so it is that track's target seen with another heading (a vote for the
        180-degree ambiguity when it is 180 degrees off; with ``class_votes``, for its class too;
        with ``place_hits``, a hit of a track no other detection hit this scene, its position fused).
        ``hit``: ids of the tracks hit this scene, updated.
        """
        c = self.config
        for j, d in enumerate(detections):
            if j in used:
                continue
            near = [self.tracks[t] for t in self._near(d)]
            at_place = [(t, self._gates(t, d)) for t in near if self._same_class(t, d)]
            at_place = [(t, g) for t, g in at_place if g[0] <= c.k_gate**2]
            if at_place:
                track, (_, _, flipped) = min(at_place, key=lambda tg: (tg[1][0], tg[0].id))
                if flipped and not track.yaw_ambiguous:
                    track._flips += 1
                    track.yaw_ambiguous = track._flips >= c.flip_evidence
                if c.place_hits and track.id not in hit:
                    self._fuse(track, d, stamp_ns, heading=False)  # votes too
                    hit.add(track.id)
                else:
                    self._vote(track, d)
                continue
            yaw = d.yaw_rad
            track = Track(
                id=self._next_id,
                target=d.target,
                position_m=np.asarray(d.position_m, np.float64).copy(),
                P_position=c.position_sigma_m**2 * np.eye(3),
                yaw_rad=0.0 if yaw is None else _wrap(yaw),
                yaw_var=math.inf if yaw is None else math.radians(c.yaw_sigma_deg) ** 2,
                first_seen_ns=stamp_ns,
                last_seen_ns=stamp_ns,
                supporting_stamps_ns=[stamp_ns],
                places_m=[np.asarray(d.position_m, np.float64).copy()],
                sights=[d.line_of_sight()],
                _window=[True],
            )
            self._vote(track, d)
            self._next_id += 1
            self.tracks.append(track)
            used.add(j)

    def _age(self, hit: set[int], scenes: int, stamp_ns: int) -> None:
        c = self.config
        kept = []
        for track in self.tracks:
            if track.first_seen_ns == stamp_ns:  # born this scene
                track.state = "confirmed" if c.confirm_hits <= 1 else "tentative"
                kept.append(track)
                continue
            seen = track.id in hit
            missed = scenes - 1 + (0 if seen else 1)  # a gap's scenes are misses too
            track._window = [*track._window, *([False] * (scenes - 1)), seen][-c.confirm_window :]
            track._misses = 0 if seen else track._misses + missed
            if track._misses > self._max_misses(track):
                continue  # deleted
            if track.state == "tentative":
                if sum(track._window) >= c.confirm_hits and self._class_recurs(track):
                    track.state = "confirmed"
            elif seen:
                track.state = "confirmed"
            else:
                track.state = "lost"
            kept.append(track)
        self.tracks = kept
