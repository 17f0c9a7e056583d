"""Parameters of the tracker that fuses per-scene detections into confirmed targets (ours, not the paper's).

Every gate is a named multiple ``k_*`` of one physical scale: the per-detection position uncertainty
``position_sigma_m`` (metres) or heading uncertainty ``yaw_sigma_deg``. Ages count scenes (one Detections
message is one scene); a gap in the stamps counts as the scenes it spans (docs/tracking.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from atr._bounds import bounded, check_fields
from atr.errors import ConfigError


@dataclass(frozen=True)
class TrackingConfig:
    """How detections are associated, confirmed, fused and aged.

    Attributes:
        position_sigma_m: standard deviation of one detection's position along each axis, metres. A quarter
            of the 2 m TP bound (§III-C): a detection the paper counts as right lies within 4 sigma.
        yaw_sigma_deg: standard deviation of one detection's heading, degrees.
        k_gate: association gate on position, in standard deviations of the innovation (Mahalanobis
            distance over x, y, z; 3.5 keeps 99 % of a 3-dof Gaussian's samples).
        k_heading_gate: association gate on heading, in standard deviations of the heading innovation.
        k_process: position random walk per scene / position_sigma_m: how far a track's belief may move
            between scenes (a parked vehicle creeping, or the navigation drifting under the cloud).
        yaw_process_deg: heading random walk per scene, degrees.
        confirm_hits: M of "M of N": hits within the last `confirm_window` scenes that confirm a track.
        confirm_window: N of "M of N", scenes.
        delete_after_misses: consecutive missed scenes after which a confirmed (then lost) track is deleted.
            The matcher misses runs of scenes at low obliquity while the vehicle stays where it was;
            chosen on tuning seed 101 (docs/tracking.md): 20 keeps every run's track F1 >= 0.976
            where 5 gave 0.847 at 100 m, 0 degrees, with the same false tracks.
        miss_patience_per_hit: a confirmed track is deleted after max(delete_after_misses,
            miss_patience_per_hit x its hits) consecutive misses, not delete_after_misses alone: a
            parked vehicle seen in forty scenes is still there after twenty in which the matcher failed
            (at 100 m and 0 degrees it misses runs of 25-30 scenes while the orbit shows the vehicle
            end-on), where a false track, seen a few times, goes as soon as before. 2: chosen on
            tuning seeds 101-102 (T-72, every scene of scenarios 1-2; docs/tracking.md, "A track seen
            often is kept longer"): track F1 0.952 -> 0.970 and 0.967 -> 0.974, per-scene F1 0.909
            -> 0.918 and 0.927 -> 0.934 (a kept track's place is confirmed again when the view
            comes back), the same false tracks; 1 re-scored 0.962 on seed 101. 0: off.
        flip_evidence: detections at a track's place whose heading is 180 degrees off it before the track
            treats heading as known only modulo 180 degrees (a vehicle whose ends look alike to the matcher).
        supporting_max: how many of the latest supporting detections' stamps a track keeps.
        fuse_median: the fused position is the geometric median of the track's latest `fuse_window`
            detections, not the filter's mean: the matcher's errors are mostly small with a few fits
            that slid a metre or more (a vehicle half behind a building), and a median ignores those.
            Chosen on tuning seed 101 (every scene of scenarios 1-2): fused error at 100 m 0.12-0.23 ->
            0.08-0.17 m, at 50 m 0.06-0.11 -> 0.05-0.08 m, track F1 and false tracks the same
            (docs/tracking.md). The covariance stays the filter's.
        fuse_line_of_sight_weight: in the median, the weight of a detection's offset along its
            horizontal line of sight (``TrackInput.viewpoint_m``) against 1 across it: an SfM cloud
            is least sure in depth, and the matcher's fits sit a few centimetres to a decimetre beyond
            or before the vehicle as the camera sees it, an offset that turns with the view and that
            a median over a part of the orbit keeps. 0.25 (depth twice as uncertain as the rest):
            chosen on tuning seeds 101 and 102 (every scene at 100 m, seed 101 at 50 m too; 1 is the
            plain median; on seed 101 0.1 and 0.5 came within 0.03 m of 0.25 on every run, neither
            better on all): fused error at 100 m 0.06-0.18 -> 0.05-0.16 m, seed 101's run 2-3
            0.14 -> 0.09 m, at 50 m 0.01-0.06 m either way (docs/tracking.md).
        fuse_window: scenes of detections the median runs over: a parked vehicle's, about two thirds of
            an orbit at one scene a second (64 and 128 measured the same on the tuning seed, 32 worse
            at 100 m); a vehicle that moves within the gate is followed once half the window saw it there.
        place_hits: a detection of a track's class at its place that association did not give it (its
            heading outside the gate: most often 180 degrees off) is a hit: one vehicle per place, so
            it counts towards M of N and its position is fused; its heading is not. Chosen on tuning
            seed 101 (every scene of scenarios 1-2): one more TP scene, 100 m 0 degrees confirmed a
            scene sooner, the same false tracks, the fused error there 0.17 -> 0.21 m. Not fusing the
            position leaves a track born with a wrong heading where it was born (docs/tracking.md).
        class_votes: a track is a place, not a class: detections of any class associate with it, each
            adds its score to its class's evidence, and the track's class is the leading one. Look-alike
            templates that win one vehicle's place in turn along an orbit then make one track of the
            class seen most, not one track per class (ours, off by default: docs/tracking.md).
        class_recurs: with class_votes, a place confirms only once its leading class itself has been
            detected there confirm_hits times: a place that look-alike templates win in turn, each
            once, stays tentative (ours; on, so that class_votes brings it: chosen on tuning seeds
            101-102, where it kept most of the votes' track F1 and the false confirmed tracks of one
            track per class, docs/tracking.md).
        guided_search: between whole-cloud searches the matcher only confirms, by ICP at their poses, the
            tracks its own detections make (``atr.tracking.guided_search``; ours, on by default: on the
            tuning seeds it found as many targets or more, among look-alikes more, at a tenth of the
            time or less, docs/tracking.md). The paper's arms decide each scene alone (``preset=paper``).
        guided_sfm: with guided_search, a guided scene's SfM step matches only the image window that
            holds the search regions (``atr.sfm.dense``): the dense step costs what the window does.
        guided_place_classes: with guided_search, a guided scene lays at a track's pose only the
            templates of the classes whose tracks stand at that place (a whole search gave it to
            them), not every template: among a family of eleven most of a guided scene is ICP of
            templates no whole search put there.
        guided_class_cylinders: with guided_place_classes, a held track's search cylinder is sized
            by the classes held at its place, not by the largest template: only they are laid there,
            and the image windows the SfM step matches shrink with the cylinders (a car's is a third
            of a main battle tank's).
        guided_whole_lays_all: with guided_search, a whole search also lays every template at each
            live track's pose and refines it by ICP, the fits competing with the searched ones: a guided
            scene lays at a place only the classes held there, so a place a look-alike's template won
            once would stay its own until the descriptors found the target there again. Chosen on
            tuning seeds 101-102 (docs/tracking.md, "Every template at the held places").
        guided_reacquire_misses: with guided_search, once a confirmed track has gone unconfirmed
            this many scenes in a row the next scene is searched whole (once per loss; 0: never, the
            default): a guided scene looks for a held target only at its fused pose, and one whose
            fit there failed could be found again by the descriptors while its track still holds.
            Off: on the tuning seeds (every scene of scenarios 1-2) it lifted the T-72's track F1 on
            seed 101 and lowered it on seed 102, with more false tracks (docs/tracking.md,
            "Searching whole when a target is lost").
        full_search_every_frames: with guided_search, a scene searches the whole cloud once this many
            camera frames have passed since the last whole search (``SearchSchedule``): frames, not
            scenes, so that a flight whose every pair is a scene and the evaluation's sampled flights
            (``atr eval --every 5``) search whole at the same places on the orbit. 15 (every third
            scene of every fifth; one in fifteen of a flight whose every pair is a scene): chosen
            against 20 and 10 on tuning seeds 101-102 (docs/tracking.md, "Whole searches every 15
            frames"): every 5th scene, T-72 F1 0.957 -> 0.969, the M113 among eleven 0.846 -> 0.856,
            the HMMWV among eleven 0.809 -> 0.852; every scene, track F1 0.970 -> 0.974 and 0.974 ->
            0.978, false confirmed tracks 3 -> 2. A target a whole search misses (at low obliquity
            most whole searches find no hypothesis at a half-hidden vehicle) is looked for again
            sooner. 10 made half the sampled scenes whole searches (the M113 0.834, each run's median
            scene a whole search among eleven).
        whole_search_lag_frames: with guided_search, a whole search that comes due while a track is
            held does not answer the scene that starts it: that scene is answered as a guided one (the
            held tracks confirmed where they stand), the whole search runs beside the next scenes
            (``atr.tracking.lane``; in the matcher service a worker process of its own), and its
            detections join the scene this many camera frames later: added where that scene found
            nothing, deciding the class where it found another (``GuidedSearch``). The joining scene
            is fixed by frame numbers, so the answers do not depend on how fast the search ran. While
            no track is held a whole search answers its own scene: handing those over too lost the
            first scenes of every flight and let a look-alike keep a target's place. 8: 0.8 s at ten
            frames a second, more than a whole search's 0.45-0.9 s in the worker beside the other
            services, so a scene seldom waits for one. Chosen on tuning seeds 101-102 (docs/
            tracking.md, "Whole searches that answer late"): 6 against 0, every 5th scene, the
            T-72's F1 0.956 -> 0.957; every scene, pooled 0.925 -> 0.918, the target that a whole
            search finds while a confuser's track is held being found six frames later; then 8
            against 6 with whole searches every 15 frames, which at 6 made the graph's last scene
            wait for the search that joined it (a scene every 100-103 ms, at 8 99-100 ms): every
            scene, F1 0.921 -> 0.920 and 0.936 -> 0.937, track F1 0.974 -> 0.972 and 0.978 -> 0.976;
            with ``atr eval --every 5`` both join the same sampled scene. 0: every whole search
            answers its own scene.
        try_tentative_first: with guided_search, a whole search that comes due while only tentative
            tracks are held (a flight's start) first lays each one's own class at its pose (refined by
            ICP in its cylinder), then, when each is accepted, every template; when each tentative
            track's own class wins its place again that is the scene's answer and the whole search is
            skipped (its cloud is matched whole all the same, so the schedule counts it as whole).
            Until a track is held every scene is a whole search (0.45-0.53 s among three
            templates), and at ten frames a second the first two set the service graph's latency
            for the flight's first second or more: with the try its p95
            over a 121-frame flight is 149-258 ms against 651-709 ms (docs/performance.md, "The service
            graph at the camera's pace"). Chosen on tuning seeds 101-102: every 5th scene, the T-72
            0.969 -> 0.973, the M113 and the HMMWV among eleven unchanged; every scene unchanged
            (docs/tracking.md, "Tentative tracks tried first").
        k_search_radius: a held track's search cylinder's radius / the largest footprint (length +
            width) of the templates laid at its place (guided_class_cylinders; else of every template):
            a vehicle at the track's place is inside at any heading (its half-diagonal is under half
            the footprint) with ground around it. Chosen on tuning seeds 101-102 (T-72):
            0.6 gave the same pooled F1 as 1.0 (0.928) at 1.12-1.16 x the reference workload per scene
            against 1.61-1.70 x, its window in the images being smaller (docs/tracking.md).

    """

    position_sigma_m: float = bounded(0.5, gt=0)
    yaw_sigma_deg: float = bounded(10.0, gt=0)
    k_gate: float = bounded(3.5, gt=0)
    k_heading_gate: float = bounded(3.0, gt=0)
    k_process: float = bounded(0.1, ge=0)
    yaw_process_deg: float = bounded(1.0, ge=0)
    confirm_hits: int = bounded(2, ge=1)
    confirm_window: int = bounded(3, ge=1)
    delete_after_misses: int = bounded(20, ge=1)
    miss_patience_per_hit: float = bounded(2.0, ge=0)
    flip_evidence: int = bounded(2, ge=1)
    supporting_max: int = bounded(32, ge=1)
    fuse_median: bool = True
    fuse_window: int = bounded(64, ge=1)
    fuse_line_of_sight_weight: float = bounded(0.25, gt=0, le=1)
    place_hits: bool = True
    class_votes: bool = False
    class_recurs: bool = True
    guided_search: bool = True
    guided_sfm: bool = True
    guided_place_classes: bool = True
    guided_class_cylinders: bool = True
    guided_whole_lays_all: bool = True
    guided_reacquire_misses: int = bounded(0, ge=0)
    full_search_every_frames: int = bounded(15, ge=1)
    whole_search_lag_frames: int = bounded(8, ge=0)
    try_tentative_first: bool = True
    k_search_radius: float = bounded(0.6, gt=0)

    def __post_init__(self) -> None:
        """Validate; raise ConfigError naming the bad value."""
        check_fields(self, prefix="tracking.")
        if self.confirm_hits > self.confirm_window:
            raise ConfigError(
                f"tracking.confirm_hits = {self.confirm_hits} must be <= confirm_window = "
                f"{self.confirm_window} (M of N)"
            )
