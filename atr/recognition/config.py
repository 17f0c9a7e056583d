"""Parameters of the 3D ATR module (paper §II-A offline phase, §II-B-2 online phase).

Every geometric threshold is a named multiple ``k_*`` of one physical scale, ``resolution_m`` (the uniform
subsampling resolution of model and scene). Values the paper gives are cited by section; the others say
where they come from (PCL's recognition tutorial, or measurements on simulator runs kept apart from the
evaluation runs, see docs/recognition.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from atr.errors import ConfigError

DESCRIPTORS: tuple[str, ...] = ("shot", "usc", "3dsc", "fpfh", "rops", "hod", "hod-s")
"""Descriptor names the matcher accepts (paper Table III)."""


@dataclass(frozen=True)
class RecognitionConfig:
    """Configuration of template building and of the online matcher.

    Attributes:
        resolution_m: uniform subsampling resolution of model and scene, metres (§II-A, §II-B-2: 0.3 m).
            Every geometric threshold below is a multiple of it.
        normal_k: neighbours of the plane fit that gives each vertex its normal (§II-B-2: six).
        knndr_k: k of the kNNDR matching (§II-B-2: k = 10).
        ransac_iterations: RANSAC iterations per correspondence group (§II-B-2: 1000).
        descriptor: default 3D descriptor, one of ``DESCRIPTORS`` (Table III).
        k_support_radius: descriptor support radius / resolution. The paper uses rho x r with rho "as
            suggested by the authors of each descriptor" (§III-B); PCL's tutorial advises 5-20 x the
            mean spacing. 5 x 0.3 m = 1.5 m covers a T-72 turret or hull corner (~80 vertices).
        smooth_angle_rad: a vertex whose normal deviates from its neighbours' normals by less than this
            mean angle lies on a smooth surface and is filtered out of the keypoints (§II-B-2). 10 deg keeps
            edges and curved parts and removes ground, roofs and walls (measured, docs/recognition.md).
        knndr_ratio: a model descriptor among the k nearest is kept as a correspondence when its distance is
            below this fraction of the k-th (the "background") distance. 0.8 is Lowe's NNDR value, also the
            paper's 2D threshold (§III-B).
        max_correspondences: keep at most this many best correspondences before grouping (bounds the
            quadratic grouping time on 260k-point LIDAR scenes).
        knn_across_views: with a multi-view template, take each keypoint's k nearest over all views of its
            elevation ring together instead of k per view (k-fold fewer correspondences; measured in
            docs/recognition.md).
        k_consensus: geometric-consistency tolerance / resolution: two correspondences agree when their
            scene and model distances differ by less than this (PCL GeometricConsistencyGrouping gc_size).
            Two voxels' worth covers the subsampling jitter of both clouds.
        min_group_size: smallest consistent group given to RANSAC (PCL tutorial cg_thresh = 5).
        max_groups: at most this many groups (largest first) become RANSAC hypotheses. 20: more than 10
            let T-72 fits on roofs through until the terrain rule below removed them; with it 20 scores
            higher with six of the seven descriptors on both tuning sets (docs/recognition.md, "Roofs").
        k_ransac_inlier: RANSAC inlier distance / resolution (one voxel of jitter on each side).
        k_same_hypothesis: two RANSAC hypotheses of one template view whose poses differ by less than
            this / resolution in translation and ``same_hypothesis_deg`` in rotation are verified once
            (a time setting: ICP from starts this close ends alike; docs/recognition.md).
        same_hypothesis_deg: see ``k_same_hypothesis``.
        k_icp_gate: ICP maximum correspondence distance / resolution (Open3D's registration example
            uses 0.4-1.5 x voxel; 2 lets ICP pull in a hypothesis that RANSAC placed a voxel off).
        icp_iterations: ICP iterations in verification (Open3D's default 30).
        k_icp_reach: ICP refines a hypothesis on the scene vertices within the model's radius, the ICP
            gate and this / resolution of where RANSAC placed it (3 m), not on the whole scene; a
            hypothesis that moves further is refined again on the whole scene, so the outcome does not
            change (tuning set: ICP moves a hypothesis's centre 0.35 m median, 2.2 m at the 99th
            percentile). It is a time setting: a kd-tree of the neighbourhood instead of the scene.
        k_overlap: a model vertex overlaps the scene when a scene vertex lies within this distance / resolution.
        min_overlap: a hypothesis is accepted when at least this fraction of the model's vertices overlap the
            scene after ICP (§II-B-2 "overlapping vertices that exceed a threshold"; the paper gives no
            value). Measured on the tuning set: true-pose overlaps of sparse SfM clouds are 0.3-0.5, and
            0.3 scores higher than 0.4 with every descriptor, LIDAR unchanged (docs/recognition.md).
        min_overlap_vertices: and at least this many model vertices overlap (rejects tiny accidental fits).
        max_clutter: and at most this fraction of the scene vertices inside the model's box is left unexplained
            by the model (rejects box-like models laid on buildings, and small confusers laid on a bigger
            vehicle). A light form of PCL's global hypothesis verification clutter term.
        k_clutter_sigma: a scene vertex with a position uncertainty sigma (SfM clouds carry one per
            point) is explained by the model within max(k_overlap x resolution, this x sigma): depth noise
            is not clutter (measured in docs/recognition.md).
        k_ground_slab: the bottom of the model's box, this / resolution high, is ignored by the clutter measure
            (the ground under and around the target is not part of the model).
        k_nms: hypotheses whose target centres are closer than this / resolution are one location; only the
            best-scoring target is reported there (recognition between the T-72 and its confusers).
        max_scene_points: scenes larger than this are refused (InputError) before any work.
        max_scene_keypoints: at most this many filtered scene vertices are described (evenly thinned,
            deterministic); bounds the describe time on dense LIDAR scenes.
        ground_vehicles: the targets are ground vehicles in a z-up world frame (template frame: origin on the
            ground, z up, as ``atr.sim.vehicles``). Then the scene's ground is estimated
            (``steps.height_above_ground``) and removed from the description surface, the template is cut
            at the same height, and keypoints are restricted to the height band a target can occupy. It
            replaces the smooth-surface filter's job on the ground, which SfM noise defeats
            (docs/recognition.md). Applied only when every template says it stands on the ground.
        k_ground_cell: ground grid cell / resolution (1.5 m cells: several SfM points per cell).
        k_ground_window: half-size of the ground percentile window / resolution (4.5 m: wider than half a
            T-72, so the ground around a vehicle wins over its roof).
        ground_percentile: percentile of the window's lowest-point cells taken as ground.
        k_ground_cut: scene vertices less than this / resolution above the ground are ground; template
            vertices lower than it above the model's base are dropped alike.
        k_keypoint_min_height: keypoints lie at least this / resolution above the ground (and at most the
            tallest template's height above it).
        hough_yaw_bin_deg: heading bin of the upright Hough grouping (``steps.group_upright_hough``), used
            for ground vehicles instead of pairwise consistency; 10 deg moves a point 3.5 m from the
            centre by 0.6 m, about one accumulator cell.
        k_hough_cell: position cell of the Hough accumulator / resolution.
        k_terrain_window: half-size of the window around a hypothesis in which the terrain under it is
            estimated / resolution (18 m: wider than most roofs, so the streets and yards around a
            building set it).
        k_terrain_step: a ground vehicle's base may lie at most this / resolution above that terrain
            (1.5 m). A hypothesis higher up stands on a roof or a wall top: impossible for a ground
            vehicle. One-storey roofs are >= 3 m up. On a slope the window's 20th percentile lies
            downhill of the centre, by ~0.6 x the half-window x the gradient, so slopes up to ~14 %
            pass (docs/recognition.md, "Roofs").
        k_height_tol: a correspondence is kept only if the scene vertex's height above the ground and the
            model vertex's height differ by less than this / resolution (SfM depth noise ~ 0.1-0.3 m).
        view_yaw_margin_deg: with per-view templates and a known camera position, a view votes only for
            headings that put the camera within half the view spacing plus this margin of its azimuth.
        template_samples_per_m2: dense surface sampling of the CAD mesh before HPR (§II-A), points per m^2.
        template_elevations_deg: elevations of the HPR viewpoint rings (§II-A); each ring has a view per
            azimuth, and the matcher uses for each scene vertex the ring nearest the camera's elevation seen
            from it (the camera position is known). 30 deg is
            the paper's medium obliquity, from which its 2D templates were taken (§III-D).
        template_azimuths_deg: azimuths of the HPR viewpoints; each (azimuth, elevation) is a separate view of the
            template, matched, grouped and verified on its own (12 views every 30 deg: measured in
            docs/recognition.md, one view only recognises within about +-30 deg of it). One view is the
            paper's choice (§II-A), several cover the orbit's 360 deg (docs/recognition.md).
        template_distance_m: distance of the HPR viewpoints from the model centre (scenario 1 range, Table II).
        hpr_radius_factor: Open3D HPR spherical-flip radius as a multiple of the viewpoint distance
            (Katz et al. 2007; Open3D's example uses 100 x the diameter).

    """

    resolution_m: float = 0.3
    normal_k: int = 15
    knndr_k: int = 10
    ransac_iterations: int = 1000
    descriptor: str = "shot"
    k_support_radius: float = 10.0
    smooth_angle_rad: float = math.radians(10.0)
    knndr_ratio: float = 1.0
    max_correspondences: int = 20000
    knn_across_views: bool = False
    k_consensus: float = 2.0
    min_group_size: int = 5
    max_groups: int = 20
    k_ransac_inlier: float = 1.0
    k_icp_gate: float = 2.0
    k_same_hypothesis: float = 0.5
    same_hypothesis_deg: float = 2.0
    icp_iterations: int = 30
    k_icp_reach: float = 10.0
    k_overlap: float = 1.0
    min_overlap: float = 0.3
    min_overlap_vertices: int = 20
    max_clutter: float = 0.5
    k_clutter_sigma: float = 2.0
    k_ground_slab: float = 2.0
    k_nms: float = 10.0
    max_scene_points: int = 5_000_000
    max_scene_keypoints: int = 20_000
    ground_vehicles: bool = True
    k_ground_cell: float = 5.0
    k_ground_window: float = 15.0
    ground_percentile: float = 20.0
    k_ground_cut: float = 1.0
    k_keypoint_min_height: float = 1.5
    hough_yaw_bin_deg: float = 10.0
    k_hough_cell: float = 3.0
    k_terrain_window: float = 60.0
    k_terrain_step: float = 5.0
    k_height_tol: float = 1.5
    view_yaw_margin_deg: float = 15.0
    template_samples_per_m2: float = 400.0
    template_elevations_deg: tuple[float, ...] = (10.0, 35.0)
    template_azimuths_deg: tuple[float, ...] = tuple(30.0 * i for i in range(12))
    template_distance_m: float = 50.0
    hpr_radius_factor: float = 100.0

    def __post_init__(self) -> None:
        """Validate every field; raise ConfigError naming the bad value."""
        if self.descriptor not in DESCRIPTORS:
            raise ConfigError(f"descriptor {self.descriptor!r} must be one of {DESCRIPTORS}")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("descriptor", "template_azimuths_deg", "template_elevations_deg"):
                continue
            if f.name in ("ground_vehicles", "knn_across_views"):
                if not isinstance(value, bool):
                    raise ConfigError(f"{f.name} = {value!r} must be true or false")
                continue
            if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise ConfigError(f"{f.name} = {value!r} must be a finite number > 0")
        if self.normal_k < 3:
            raise ConfigError(f"normal_k = {self.normal_k} must be >= 3 (a plane needs 3 points)")
        if self.knndr_k < 2:
            raise ConfigError(
                f"knndr_k = {self.knndr_k} must be >= 2 (a ratio needs two distances)"
            )
        if not 0 < self.knndr_ratio <= 1:
            raise ConfigError(f"knndr_ratio = {self.knndr_ratio} must be in (0, 1]")
        if not 0 < self.max_clutter <= 1:
            raise ConfigError(f"max_clutter = {self.max_clutter} must be in (0, 1]")
        if not 0 < self.min_overlap <= 1:
            raise ConfigError(f"min_overlap = {self.min_overlap} must be in (0, 1]")
        if self.min_group_size < 3:
            raise ConfigError(
                f"min_group_size = {self.min_group_size} must be >= 3 (a pose needs 3)"
            )
        if not 0 <= self.ground_percentile <= 100:
            raise ConfigError(f"ground_percentile = {self.ground_percentile} must be in [0, 100]")
        if not self.template_azimuths_deg:
            raise ConfigError(
                "template_azimuths_deg is empty; at least one HPR viewpoint is needed"
            )
        if not self.template_elevations_deg or not all(
            -90.0 < e <= 90.0 for e in self.template_elevations_deg
        ):
            raise ConfigError(
                f"template_elevations_deg = {self.template_elevations_deg} must be non-empty, each in (-90, 90]"
            )

    # Derived thresholds, metres.
    @property
    def support_radius_m(self) -> float:
        """Descriptor support radius, metres."""
        return self.k_support_radius * self.resolution_m

    @property
    def consensus_m(self) -> float:
        """Geometric-consistency tolerance, metres."""
        return self.k_consensus * self.resolution_m

    @property
    def ransac_inlier_m(self) -> float:
        """RANSAC inlier distance, metres."""
        return self.k_ransac_inlier * self.resolution_m

    @property
    def same_hypothesis_m(self) -> float:
        """Translation under which two hypotheses of one view are verified once, metres."""
        return self.k_same_hypothesis * self.resolution_m

    @property
    def icp_gate_m(self) -> float:
        """ICP maximum correspondence distance, metres."""
        return self.k_icp_gate * self.resolution_m

    @property
    def icp_reach_m(self) -> float:
        """How far ICP may move a hypothesis on its cropped neighbourhood, metres."""
        return self.k_icp_reach * self.resolution_m

    @property
    def overlap_m(self) -> float:
        """Model-scene overlap distance, metres."""
        return self.k_overlap * self.resolution_m

    @property
    def ground_slab_m(self) -> float:
        """Height of the ground slab ignored by the clutter measure, metres."""
        return self.k_ground_slab * self.resolution_m

    @property
    def ground_cut_m(self) -> float:
        """Height below which scene and template vertices count as ground, metres."""
        return self.k_ground_cut * self.resolution_m

    @property
    def terrain_window_m(self) -> float:
        """Half-size of the terrain window around a hypothesis, metres."""
        return self.k_terrain_window * self.resolution_m

    @property
    def terrain_step_m(self) -> float:
        """Highest a ground vehicle's base may stand above the terrain around it, metres."""
        return self.k_terrain_step * self.resolution_m

    @property
    def nms_m(self) -> float:
        """Distance under which two hypotheses are one location, metres."""
        return self.k_nms * self.resolution_m
