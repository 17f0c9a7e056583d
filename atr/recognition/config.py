"""Parameters of the 3D ATR module (paper §II-A offline phase, §II-B-2 online phase).

Three parts: what shapes a template (``TemplateConfig``), the online matcher (``MatcherConfig``) and the
ground-vehicle prior (``GroundConfig``). ``RecognitionConfig`` holds them and is the group users set:
``--set recognition.knndr_k=5`` (or ``recognition.matcher.knndr_k=5``) reaches the part that owns the field.

Every geometric threshold is a named multiple ``k_*`` of one physical scale, ``resolution_m`` (the uniform
subsampling resolution of model and scene). Values the paper gives are cited by section; the others say
where they come from (PCL's recognition tutorial, or measurements on simulator runs kept apart from the
evaluation runs, see docs/recognition.md).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, Literal, get_args

from atr._bounds import Bounds, bounded, check_fields
from atr.errors import ConfigError

Descriptor = Literal["shot", "usc", "3dsc", "fpfh", "rops", "hod", "hod-s"]
DESCRIPTORS: tuple[str, ...] = get_args(Descriptor)
"""Descriptor names the matcher accepts (paper Table III)."""

_POSITIVE = Bounds(gt=0)
"""Every number of the three parts is a positive multiple, count or size unless its field says more."""


@dataclass(frozen=True)
class TemplateConfig:
    """What shapes a template (§II-A), and so the scene's description, which must match it.

    The template cache is keyed on this part alone: changing a matcher or ground setting rebuilds nothing.
    The scene is subsampled, given normals and cut at the ground exactly as the template was.

    Attributes:
        resolution_m: uniform subsampling resolution of model and scene, metres (§II-A, §II-B-2: 0.3 m).
            Every geometric threshold below is a multiple of it.
        normal_k: neighbours of the plane fit that gives each vertex its normal, in the template and in
            the scene alike. The paper uses six (§II-B-2); 15 is ours: SfM depth noise needs the wider fit
            (docs/recognition.md, "Steps and choices").
        descriptor: 3D descriptor of the templates and the scene, one of ``DESCRIPTORS`` (Table III).
        k_support_radius: descriptor support radius / resolution. The paper uses rho x r with rho "as
            suggested by the authors of each descriptor" (§III-B); PCL's tutorial advises 5-20 x the
            mean spacing. 10 x 0.3 m = 3 m was measured on the tuning set (docs/recognition.md).
        ground_vehicles: the targets are ground vehicles in a z-up world frame (template frame: origin on the
            ground, z up, as ``atr.sim.vehicles``). Then the scene's ground is estimated
            (``steps.height_above_ground``) and removed from the description surface, the template is cut
            at the same height, and keypoints are restricted to the height band a target can occupy. It
            replaces the smooth-surface filter's job on the ground, which SfM noise defeats
            (docs/recognition.md). Applied only when every template says it stands on the ground.
        k_ground_cut: scene vertices less than this / resolution above the ground are ground; template
            vertices lower than it above the model's base are dropped alike.
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
        compact_descriptors: the store keeps and serves descriptors as uint8 codes with a per-row offset
            and step (``template.quantize_descriptors``), a quarter of float32's bytes; the matcher decodes
            them. Measured on the tuning seeds with no loss of F1 (docs/recognition.md, "Compact
            templates"); False keeps float32.

    """

    resolution_m: float = 0.3
    normal_k: int = bounded(15, ge=3, why="a plane needs 3 points")
    descriptor: Descriptor = "shot"
    k_support_radius: float = 10.0
    ground_vehicles: bool = True
    k_ground_cut: float = 1.0
    template_samples_per_m2: float = 400.0
    template_elevations_deg: tuple[float, ...] = (10.0, 35.0)
    template_azimuths_deg: tuple[float, ...] = tuple(30.0 * i for i in range(12))
    template_distance_m: float = 50.0
    hpr_radius_factor: float = 100.0
    compact_descriptors: bool = True

    def __post_init__(self) -> None:
        """Validate every field; raise ConfigError naming the bad value."""
        check_fields(self, numbers_default=_POSITIVE)
        _check_template(self)

    @property
    def support_radius_m(self) -> float:
        """Descriptor support radius, metres."""
        return self.k_support_radius * self.resolution_m

    @property
    def ground_cut_m(self) -> float:
        """Height below which scene and template vertices count as ground, metres."""
        return self.k_ground_cut * self.resolution_m


@dataclass(frozen=True)
class MatcherConfig:
    """The online matcher's settings (§II-B-2): keypoints, matching, grouping, RANSAC, verification.

    Distances are multiples ``k_*`` of the template part's ``resolution_m``.

    Attributes:
        max_scene_points: scenes larger than this are refused (InputError) before any work.
        max_scene_keypoints: at most this many filtered scene vertices are described (evenly thinned,
            deterministic); bounds the describe time on dense LIDAR scenes.
        smooth_angle_rad: a vertex whose normal deviates from its neighbours' normals by less than this
            mean angle lies on a smooth surface and is filtered out of the keypoints (§II-B-2). 10 deg keeps
            edges and curved parts and removes ground, roofs and walls (measured, docs/recognition.md).
        knndr_k: k of the kNNDR matching (§II-B-2: k = 10).
        knndr_ratio: a model descriptor among the k nearest is kept as a correspondence when its distance is
            below this fraction of the k-th (the "background") distance. 0.8 is Lowe's NNDR value, also the
            paper's 2D threshold (§III-B); 1.0 (every one of the k - 1 nearest is a candidate, the grouping
            does the rejecting) scores higher on SfM clouds (docs/recognition.md).
        max_correspondences: keep at most this many best correspondences before grouping (bounds the
            quadratic grouping time on 260k-point LIDAR scenes).
        knn_across_views: with a multi-view template, take each keypoint's k nearest over all views of its
            elevation ring together instead of k per view (k-fold fewer correspondences; measured in
            docs/recognition.md).
        ring_reach_deg: a scene keypoint meets the views of the elevation ring nearest the camera's
            elevation seen from it and of every ring within this many degrees of that elevation. 0:
            the nearest ring only. 10 beside a 0-degree ring cost the T-72 on the tuning seed
            (docs/recognition.md, "A third ring at 0°").
        k_consensus: geometric-consistency tolerance / resolution: two correspondences agree when their
            scene and model distances differ by less than this (PCL GeometricConsistencyGrouping gc_size).
            Two voxels' worth covers the subsampling jitter of both clouds.
        min_group_size: smallest consistent group given to RANSAC (PCL tutorial cg_thresh = 5).
        max_groups: at most this many groups (largest first) become RANSAC hypotheses. 20: more than 10
            let T-72 fits on roofs through until the terrain rule below removed them; with it 20 scores
            higher with six of the seven descriptors on both tuning sets (docs/recognition.md, "Roofs").
        hough_yaw_bin_deg: heading bin of the upright Hough grouping (``steps.group_upright_hough``), used
            for ground vehicles instead of pairwise consistency; 10 deg moves a point 3.5 m from the
            centre by 0.6 m, about one accumulator cell.
        k_hough_cell: position cell of the Hough accumulator / resolution.
        view_yaw_margin_deg: with per-view templates and a known camera position, a view votes only for
            headings that put the camera within half the view spacing plus this margin of its azimuth.
        ransac_iterations: RANSAC iterations per correspondence group (§II-B-2: 1000).
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
        k_nms: hypotheses whose target centres are closer than this / resolution (or half the larger
            target) are one place, and the place goes to one template (``atr.recognition.competition``).
        cue_places: ground vehicles: every vehicle-sized blob of the scene (``atr.recognition.attention``)
            where no template's hypothesis was accepted is also tried without descriptors: each template
            is laid there, its camera-facing view on the blob, at ``cue_headings`` headings, and verified
            like a RANSAC hypothesis (docs/recognition.md, "Cued places"). Finds targets whose keypoints
            gave no consistent group (a grazing side view).
        cue_headings: headings tried at a cued place: the blob's long axis and its turns by 360 / this
            degrees (4: along and across it, both ways).
        cue_max_tilt_deg: a cued hypothesis is accepted only if ICP left the vehicle's up axis within
            this of vertical: a vehicle stands on its wheels or tracks on drivable ground (10 deg is an
            18 % slope), and with no descriptor evidence a tilted fit is a template draped over a part
            of something else.
        max_fits_per_place: a template's hypothesis is not verified once this many of its accepted
            fits stand within ``k_nms`` of where it would place the target (0: every hypothesis is
            verified). A time setting: the place competition takes each template's strongest fit per
            place, and most hypotheses of a found vehicle end in the same fit. Tuning seeds 101-102,
            T-72 and its two confusers: 4 gives the same F1 (0.939 / 0.922 -> 0.939 / 0.919) with
            ICP 74-76 -> 41-42 ms and 8-10 % less time per scene; 2 and 1 lose targets; with the
            whole family as templates 4 loses some (F1 0.758 -> 0.746), so it is off (docs/
            recognition.md, "Repeated hypotheses").
        icp_point_to_plane: verification's ICP minimises distances to the scene's local planes (its
            own normals) rather than to its points (``steps.VerifySettings.point_to_plane``), where
            ``k_plane_sigma`` and ``plane_min_normal_spread`` allow. Point-to-point ICP holds a fit
            where the template's and the scene's samples pair, a few centimetres along the hull.
            Tuning seeds 101-102, T-72, every 5th scene: pooled F1 0.931 -> 0.944, run medians at 50 m
            0.08-0.15 -> 0.07-0.13 m; the whole family level (0.758 -> 0.756); time +2 % (docs/
            recognition.md, "Point-to-plane ICP"). The committed evaluation predates it.
        k_plane_sigma: with ``icp_point_to_plane``, ICP fits to the planes only where the median
            sigma of the scene vertices it fits is at most this / resolution, and to the points
            elsewhere: the normals of a noisier cloud let the fit slide along the vehicle. Tuning
            seed 101: median sigma on the target 0.23-0.24 m at 50 m, 0.45-0.47 m at 100 m
            (``bench/scene_sigma.py``).
        plane_min_normal_spread: with ``icp_point_to_plane``, ICP fits to the planes only where the
            normals of the scene vertices it fits cover all three directions: the smallest eigenvalue
            of their mean outer product at least this (``steps.normal_spread``; 1/3 for an even
            spread, 0 for flat ground or one wall, where the planes leave the pose free and Open3D's
            solve differs from run to run). Tuning seed 101, T-72, every 5th scene: 0.7 % of the
            fits fall below 0.01, the 1st percentile is 0.019, the median 0.14.

    """

    max_scene_points: int = 5_000_000
    max_scene_keypoints: int = 20_000
    smooth_angle_rad: float = math.radians(10.0)
    knndr_k: int = bounded(10, ge=2, why="a ratio needs two distances")
    knndr_ratio: float = bounded(1.0, gt=0, le=1)
    max_correspondences: int = 20000
    knn_across_views: bool = False
    ring_reach_deg: float = bounded(0.0, ge=0, le=90)
    k_consensus: float = 2.0
    min_group_size: int = bounded(5, ge=3, why="a pose needs 3")
    max_groups: int = 20
    hough_yaw_bin_deg: float = 10.0
    k_hough_cell: float = 3.0
    view_yaw_margin_deg: float = 15.0
    ransac_iterations: int = 1000
    k_ransac_inlier: float = 1.0
    k_same_hypothesis: float = 0.5
    same_hypothesis_deg: float = 2.0
    k_icp_gate: float = 2.0
    icp_iterations: int = 30
    k_icp_reach: float = 10.0
    k_overlap: float = 1.0
    min_overlap: float = bounded(0.3, gt=0, le=1)
    min_overlap_vertices: int = 20
    max_clutter: float = bounded(0.5, gt=0, le=1)
    k_clutter_sigma: float = 2.0
    k_ground_slab: float = 2.0
    k_nms: float = 10.0
    cue_places: bool = False
    cue_headings: int = bounded(4, ge=1)
    cue_max_tilt_deg: float = bounded(10.0, gt=0, le=90)
    max_fits_per_place: int = bounded(0, ge=0)
    icp_point_to_plane: bool = True
    k_plane_sigma: float = 1.0
    plane_min_normal_spread: float = bounded(0.01, ge=0, le=1 / 3)

    def __post_init__(self) -> None:
        """Validate every field; raise ConfigError naming the bad value."""
        check_fields(self, numbers_default=_POSITIVE)


@dataclass(frozen=True)
class GroundConfig:
    """The ground-vehicle prior of the matcher (docs/recognition.md, "Ground", "Roofs"): the scene's ground,
    the height band of keypoints, and where a vehicle may stand. Used when ``ground_vehicles`` is set
    and every template stands on the ground; distances are multiples of ``resolution_m``.

    Attributes:
        k_ground_cell: ground grid cell / resolution (1.5 m cells: several SfM points per cell).
        k_ground_window: half-size of the ground percentile window / resolution (4.5 m: wider than half a
            T-72, so the ground around a vehicle wins over its roof).
        ground_percentile: percentile of the window's lowest-point cells taken as ground.
        k_keypoint_min_height: keypoints lie at least this / resolution above the ground (and at most the
            tallest template's height above it).
        k_height_tol: a correspondence is kept only if the scene vertex's height above the ground and the
            model vertex's height differ by less than this / resolution (SfM depth noise ~ 0.1-0.3 m).
        k_terrain_window: half-size of the window around a hypothesis in which the terrain under it is
            estimated / resolution (18 m: wider than most roofs, so the streets and yards around a
            building set it).
        k_terrain_step: a ground vehicle's base may lie at most this / resolution above that terrain
            (1.5 m). A hypothesis higher up stands on a roof or a wall top: impossible for a ground
            vehicle. One-storey roofs are >= 3 m up. On a slope the window's 20th percentile lies
            downhill of the centre, by ~0.6 x the half-window x the gradient, so slopes up to ~14 %
            pass (docs/recognition.md, "Roofs").
        k_place_radius: an accepted hypothesis is placed on the ground around it: its height is set to the
            median height of the scene's ground points within this / resolution (8.1 m, beyond a
            vehicle's half length: the ground beside it, not under it). The ground estimate above is a low
            percentile of the lowest points and stands 0.1-0.3 m below the ground at 100 m; ICP leaves the
            vehicle 0.1-0.3 m low too (docs/recognition.md, "Placing the vehicle on the ground").
        min_place_points: fewer ground points than this within the radius leave the ICP height as it is.
        k_place_band: from that median the height moves to the median of every scene vertex within
            this / resolution of it (0.3 m), repeated until it settles: the ground points are cut at
            a low percentile plus the ground cut, so in a noisy cloud they miss the ground's upper
            tail and their median stands 0.06-0.14 m low at 100 m; a band symmetric about the
            estimate does not (docs/recognition.md, "Placing the vehicle on the ground"). 0: the
            ground points' median.
        attention: take keypoints only where a vehicle can stand (``atr.recognition.attention``): in
            blobs of the height band, on columns no taller than the tallest template, whose footprint
            is vehicle-sized. Off: on the tuning seed it drops a quarter of the keypoints but only ~3 %
            of the time, with the same F1 (docs/recognition.md, "Attention").
        k_attention_cell: the attention grid's cell / resolution (0.6 m: finer than the gap between two
            parked vehicles).
        k_attention_footprint: a blob is searched when its footprint's diagonal is at most this times
            the largest template's (length + width: its diagonal at the worst heading on the grid).

    """

    k_ground_cell: float = 5.0
    k_ground_window: float = 15.0
    ground_percentile: float = bounded(20.0, gt=0, le=100)
    k_keypoint_min_height: float = 1.5
    k_height_tol: float = 1.5
    k_terrain_window: float = 60.0
    k_terrain_step: float = 5.0
    k_place_radius: float = 27.0
    min_place_points: int = 20
    k_place_band: float = bounded(1.0, ge=0)
    attention: bool = False
    k_attention_cell: float = 2.0
    k_attention_footprint: float = 1.5

    def __post_init__(self) -> None:
        """Validate every field; raise ConfigError naming the bad value."""
        check_fields(self, numbers_default=_POSITIVE)


def _check_template(part: TemplateConfig) -> None:
    if part.descriptor not in DESCRIPTORS:
        raise ConfigError(f"descriptor {part.descriptor!r} must be one of {DESCRIPTORS}")
    if not part.template_azimuths_deg:
        raise ConfigError("template_azimuths_deg is empty; at least one HPR viewpoint is needed")
    if not part.template_elevations_deg or not all(
        -90.0 < e <= 90.0 for e in part.template_elevations_deg
    ):
        raise ConfigError(
            f"template_elevations_deg = {part.template_elevations_deg} must be non-empty, "
            "each in (-90, 90]"
        )


_PART_OF: dict[str, str] = {
    f.name: part
    for part, cls in (
        ("template", TemplateConfig),
        ("matcher", MatcherConfig),
        ("ground", GroundConfig),
    )
    for f in fields(cls)
}
"""The part that owns each field, by the field's name (names are unique across the parts)."""


class _Metres:
    """A threshold of ``RecognitionConfig`` in metres: its ``k_*`` field times ``resolution_m``."""

    def __init__(self, k_field: str, doc: str) -> None:
        self.k_field = k_field
        self.__doc__ = f"{doc}, metres ({k_field} x resolution_m)."

    def __get__(self, config: RecognitionConfig | None, owner: type | None = None) -> Any:
        if config is None:  # looked up on the class (help(), docs): the descriptor itself
            return self
        return getattr(config, self.k_field) * config.template.resolution_m


@dataclass(frozen=True, init=False)
class RecognitionConfig:
    """Configuration of template building and of the online matcher: the group users set.

    It holds the three parts and forwards each field's name to the part that owns it, both ways:
    ``RecognitionConfig(knndr_k=5)``, ``dataclasses.replace(config, knndr_k=5)`` and ``config.knndr_k``
    work as on one flat group, and ``--set recognition.knndr_k=5`` reaches ``matcher.knndr_k``
    (``field_path``). The defaults are the paper's values where it gives one; each field's docstring
    says where the others come from.

    Attributes:
        template: what shapes a template (and the scene's description); keys the template cache.
        matcher: the online matcher's settings.
        ground: the ground-vehicle prior.

    """

    template: TemplateConfig
    matcher: MatcherConfig
    ground: GroundConfig

    def __init__(
        self,
        template: TemplateConfig | None = None,
        matcher: MatcherConfig | None = None,
        ground: GroundConfig | None = None,
        **fields_by_name: Any,
    ) -> None:
        """The parts (defaults where None), then any field of a part given by its name.

        Raises:
            ConfigError: an unknown field name, a part of the wrong type, or a value a part refuses.

        """
        parts: dict[str, Any] = {
            "template": TemplateConfig() if template is None else template,
            "matcher": MatcherConfig() if matcher is None else matcher,
            "ground": GroundConfig() if ground is None else ground,
        }
        for name, cls in (
            ("template", TemplateConfig),
            ("matcher", MatcherConfig),
            ("ground", GroundConfig),
        ):
            if not isinstance(parts[name], cls):
                raise ConfigError(f"recognition.{name} = {parts[name]!r} must be a {cls.__name__}")
        changes: dict[str, dict[str, Any]] = {}
        for name, value in fields_by_name.items():
            if name not in _PART_OF:
                raise ConfigError(
                    f"recognition has no field {name!r}; expected one of {sorted(_PART_OF)}"
                )
            changes.setdefault(_PART_OF[name], {})[name] = value
        for part, values in changes.items():
            parts[part] = dataclasses.replace(parts[part], **values)
        for part, value in parts.items():
            object.__setattr__(self, part, value)

    def __getattr__(self, name: str) -> Any:
        """A part's field by its name alone (``config.knndr_k`` is ``config.matcher.knndr_k``)."""
        part = _PART_OF.get(name)
        if part is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        return getattr(object.__getattribute__(self, part), name)

    @staticmethod
    def field_path(name: str) -> list[str]:
        """Where a field's name lives: ``["matcher", "knndr_k"]`` for "knndr_k"; [name] for a part."""
        return [_PART_OF[name], name] if name in _PART_OF else [name]

    # Derived thresholds, metres: each a k_* field times the template resolution (habit 6).
    support_radius_m = _Metres("k_support_radius", "Descriptor support radius")
    ground_cut_m = _Metres(
        "k_ground_cut", "Height below which scene and template vertices are ground"
    )
    consensus_m = _Metres("k_consensus", "Geometric-consistency tolerance")
    ransac_inlier_m = _Metres("k_ransac_inlier", "RANSAC inlier distance")
    same_hypothesis_m = _Metres(
        "k_same_hypothesis", "Translation under which two hypotheses of one view are verified once"
    )
    icp_gate_m = _Metres("k_icp_gate", "ICP maximum correspondence distance")
    icp_reach_m = _Metres(
        "k_icp_reach", "How far ICP may move a hypothesis on its cropped neighbourhood"
    )
    overlap_m = _Metres("k_overlap", "Model-scene overlap distance")
    plane_max_sigma_m = _Metres(
        "k_plane_sigma", "Median scene sigma up to which point-to-plane ICP fits to the planes"
    )
    ground_slab_m = _Metres(
        "k_ground_slab", "Height of the ground slab ignored by the clutter measure"
    )
    terrain_window_m = _Metres(
        "k_terrain_window", "Half-size of the terrain window around a hypothesis"
    )
    terrain_step_m = _Metres(
        "k_terrain_step", "Highest a ground vehicle's base may stand above the terrain around it"
    )
    nms_m = _Metres("k_nms", "Distance under which two hypotheses are one location")
    place_radius_m = _Metres(
        "k_place_radius", "Radius of the ground around a hypothesis that its height is set from"
    )
    place_band_m = _Metres(
        "k_place_band", "Half-width of the band about the ground height that a placement settles in"
    )
