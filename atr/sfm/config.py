"""Parameters of the two-view SfM module (paper §II-B-1), one frozen dataclass, validated on construction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from atr._bounds import bounded, check_fields
from atr.errors import ConfigError

Matcher = Literal["gftt", "surf", "sgm"]


@dataclass(frozen=True)
class SfmConfig:
    """Settings of keypoint correspondence and known-pose triangulation.

    Defaults are the paper's values (§II-B-1) where it gives one; the others cite their source.
    Pixel thresholds are in pixels of the image given to the module (no hidden rescaling).
    """

    matcher: Matcher = "gftt"
    """Correspondence scheme: "gftt" = GFTT corners tracked by KLT, "surf" = SURF + NNDR (§II-B-1), "sgm" =
    dense semi-global matching of the pair rectified with the known pose (ours, atr.sfm.dense)."""

    # --- GFTT (Shi-Tomasi corners), §II-B-1 ---
    gftt_min_quality: float = bounded(1e-3, gt=0, lt=1)
    """Minimum corner quality, relative to the strongest corner's min-eigenvalue (§II-B-1: 1e-3)."""
    gftt_filter_size_px: int = bounded(3, ge=1, odd=True)
    """Gaussian filter size (px, odd) applied before the corner metric (§II-B-1: 3x3)."""
    gftt_block_size_px: int = bounded(3, ge=1, odd=True)
    """Structure-tensor window (px, odd); MATLAB's detectMinEigenFeatures uses the filter size here too."""
    gftt_max_corners: int = bounded(20000, ge=0)
    """Corner cap (0 = none). The paper gives none; a cap bounds time. See docs/sfm.md (measured counts)."""
    gftt_min_distance_px: float = bounded(2.0, ge=0)
    """Minimum corner spacing (px). MATLAB keeps 3x3 local maxima only, i.e. corners >= ~2 px apart."""

    # --- KLT (pyramidal Lucas-Kanade), §II-B-1 ---
    klt_window_px: int = bounded(11, ge=1, odd=True)
    """Tracking window side (px), §II-B-1: 11x11."""
    klt_pyramid_levels: int = bounded(13, ge=1)
    """Pyramid levels including full resolution (§II-B-1: 13 scales); OpenCV maxLevel = levels - 1."""
    klt_iterations: int = bounded(10, ge=1)
    """Lucas-Kanade iterations per level (§II-B-1: 10)."""
    klt_epsilon_px: float = bounded(0.01, gt=0)
    """Stop iterating when the update is below this (px). OpenCV's default criteria value."""
    klt_max_forward_backward_px: float = bounded(1.0, gt=0)
    """Forward-backward error gate (px), §II-B-1 with Kalal et al. 2010 [24]: 1 px."""

    # --- Pose-aided second pass (ours, not the paper's; docs/sfm.md "Pose-aided KLT") ---
    klt_aided_pyramid_levels: int = bounded(2, ge=0)
    """Levels of a second KLT pass given to the corners the paper's tracker loses (0 = no second pass).
    It starts each corner where the known relative pose puts it if it lies on the fixation plane, so a
    shallow pyramid suffices; the deep pyramid's coarse levels are what loses a small target behind
    fast-moving foreground (0 deg obliquity). 2 levels: tuning-set F1 against 1, 3 and 4 levels in
    docs/sfm.md ("Pose-aided KLT")."""
    ground_z_m: float = bounded(0.0)
    """Height of the ground in the world (navigation) frame, metres: the take-off point's. Corners whose
    ray meets the ground before the fixation plane are foreground and get no second pass; the dense
    search reaches the nearest ground the image sees (sgm_ground_margin)."""

    # --- SURF (Bay et al. 2008), §II-B-1 ---
    surf_octaves: int = bounded(3, ge=1)
    """Number of octaves. The paper does not give it; MATLAB detectSURFFeatures default (3)."""
    surf_scale_levels: int = bounded(6, ge=3, why="extrema need a level above and below")
    """Scale levels per octave (§II-B-1: 6; MATLAB 'NumScaleLevels')."""
    surf_blob_threshold: float = bounded(2e-4, gt=0)
    """Hessian determinant threshold on an image scaled to [0, 1], box responses normalised by the
    filter area. §II-B-1 gives 1e-3, which leaves ~500 points per cloud in the paper's imagery; our
    renderer's shaded surfaces have fewer strong blobs, and 1e-3 leaves a median of 87 (tuning set, F1
    0.07). 2e-4 gives ~800 and, with surf_epipolar_guided, F1 0.49 (docs/sfm.md, "SURF for recognition")."""
    surf_initial_step_px: int = bounded(2, ge=1)
    """Sampling step of the first octave (px), doubled per octave. Bay et al. 2008 §4.2 use 2."""
    k_surf_duplicate_radius: float = bounded(1.0, ge=0)
    """Octaves overlap in filter size, so one blob can be found twice: a keypoint within this many
    scales s of a stronger one of similar scale (ratio < surf_duplicate_scale_ratio) is dropped.
    Without it, NNDR rejects both copies (measured in docs/sfm.md)."""
    surf_duplicate_scale_ratio: float = bounded(1.5, ge=1)
    """Scale ratio under which two nearby keypoints count as one blob (adjacent filter sizes of
    octave 1 differ by 1.44 at most)."""
    surf_max_keypoints: int = bounded(4000, ge=0)
    """Strongest keypoints kept per image (0 = all). Bounds the descriptor and matching time."""
    surf_upright: bool = False
    """True skips the orientation assignment (U-SURF, Bay et al. 2008 §4.3); our cameras roll."""
    surf_nndr: float = bounded(0.6, gt=0, le=1)
    """Nearest-neighbour distance ratio threshold (§II-B-1: 0.6, empirically set by the authors)."""
    surf_epipolar_guided: bool = True
    """NNDR compares each keypoint of a only with the keypoints of b within max_reprojection_px of its
    epipolar line, which the known pose gives, and the reverse (ours; the paper compares with all of b:
    False). Tuning F1 at 2e-4, best descriptor: 0.35 -> 0.49 (docs/sfm.md, "SURF for recognition")."""

    # --- Dense semi-global matching (ours, not the paper's; docs/sfm.md "Dense matching") ---
    sgm_pixel_footprint_m: float | None = bounded(0.1, gt=0)
    """The rectified images are matched at the scale at which one pixel spans this much at the pair's
    fixation depth (what the orbiting camera looks at), rounded to sgm_scale_step: with f = 2000 px, quarter
    size at 50 m (half with the default step), half at 100 m, full at 200 m. Tuning sets (SHOT), against half
    size everywhere: 200 m 0.730 -> 0.919; 100 m keeps half size. At 200 m the full-size cloud covers 4 x the
    ground of a 100 m one at the same spacing: the matcher takes 1.7 s per scene there (docs/sfm.md, "Dense
    matching"). None: every pair at sgm_scale."""
    sgm_scale_step: float = bounded(0.5, gt=0, le=1)
    """The matching scale is rounded to a multiple of this and is at least this, so a pair's scaled size
    does not wander with the range's last decimals. Halves: 50 m keeps half size, where the tuning set's
    50 m scenes give 0.960 (109/8/1, T_error 0.13 m) against 0.938 (105/9/5) at quarter size (step 0.125)
    once the dense search reaches the ground (docs/sfm.md, "Dense matching")."""
    sgm_scale: float = bounded(0.5, gt=0, le=1)
    """Matching scale of a pair whose optical axes do not converge (no fixation depth), or of every pair
    when sgm_pixel_footprint_m is None. ``./dev bench sfm`` (idle): the whole dense step takes 102 ms at half
    size against 532 ms at full size (docs/sfm.md)."""
    sgm_step_px: int = bounded(2, ge=1)
    """Every this-many-th pixel of the scaled disparity image, in rows and columns, becomes a point: 0.2 m
    apart at the fixation depth with the default footprint, against the matcher's 0.3 m subsampling."""
    sgm_disparities_px: int = bounded(384, ge=16)
    """Disparities searched at least, in full-size pixels (rounded up to OpenCV's multiple of 16 after
    scaling). A point at depth z has disparity f * baseline / z: with the simulator's baseline (7.5 % of the
    range) and f = 2000 px, 384 covers everything beyond 0.4 x the target range. The search reaches further
    where the image sees flat ground nearer (sgm_ground_margin)."""
    sgm_ground_margin: float = bounded(1.25, gt=0)
    """The search also covers this multiple of the largest disparity of the flat ground at ground_z_m that
    the first image sees (at 0 deg obliquity the camera flies 4 m up and the ground at the image's foot is
    ~15 m away), so relief and what stands on the ground near the camera are matched too. Without it such
    pixels were matched wrongly, too far, and sank metres under the target (docs/sfm.md, "Dense
    matching")."""
    sgm_block_px: int = bounded(5, ge=1, odd=True)
    """Matching block side (px, odd); OpenCV's documented 3-11 range, small for a small target."""
    k_sgm_small_jump_penalty: float = bounded(2.0, gt=0)
    """Semi-global matching's penalty P1 for a disparity change of one pixel between neighbours, as a
    multiple of the block area (px^2; OpenCV documents 8). The smoothness term pulls a small target's
    disparities towards those of the farther background around it: at 8 (and P2 at 32) the T-72's points
    at 100 m came out 0.14-0.23 px (matching scale) too small, 0.15-0.39 m too far, while the ground was
    unbiased; at 2 (and 8) 0.03-0.08 px, with no more noise. 1 (and 4) biases less still but flips more
    headings at 0 deg obliquity (tuning seed; tests/sfm/test_simulated.py)."""
    k_sgm_large_jump_penalty: float = bounded(8.0, gt=0)
    """Penalty P2 for a larger disparity change (a depth edge), as a multiple of the block area (px^2);
    OpenCV documents 32. Must exceed k_sgm_small_jump_penalty (OpenCV refuses P2 <= P1)."""
    sgm_window_ground: bool = True
    """Matching only a window (track-guided search): the search reaches the nearest ground the pixels
    whose rays cross the search regions see, not the ground at the image's foot, which at 0 deg
    obliquity lies ~15 m from the camera and makes the search (and the window, widened by it) two to
    three times larger. Only those pixels' points can fall in the regions."""
    sgm_region_bands: bool = True
    """Matching only where the search looks (track-guided search): each region is matched in its own
    window, searching only the disparities of its outline and of the ground that window sees (a band),
    instead of one window that holds every region, searched from infinity to the nearest ground. With
    a target's look-alikes held too, the one window covered most of the image (0.86 of it on the M113's
    tuning flights) and searched 192-288 disparities at half size (docs/sfm.md)."""
    sgm_uniqueness_percent: int = bounded(10, ge=0)
    """The best disparity's cost must beat the second best by this margin (%); OpenCV advises 5-15."""
    sgm_left_right_px: int = bounded(1, ge=1)
    """Left-right check: a disparity is kept when matching the other way lands within this (scaled px);
    the dense form of KLT's forward-backward check (§II-B-1 with [24])."""
    sgm_min_texture_grey: float = bounded(2.0, ge=0)
    """A pixel is matched only where the grey levels of its block vary by at least this standard
    deviation in both images (8-bit levels): flat regions get a disparity by smoothing alone."""
    sgm_speckle_window_px: int = bounded(50, ge=0)
    """Disparity blobs smaller than this (px) are removed as speckle; OpenCV advises 50-200."""
    sgm_max_rectifying_rotation_deg: float = bounded(45.0, gt=0, lt=90)
    """Rectification turns each camera until its axis is square to the baseline. Beyond this the image is
    stretched into uselessness (motion along the view axis; the epipole is in the image): empty cloud."""
    # --- Triangulation with the known (IMU) relative pose ---
    pixel_sigma_px: float = bounded(0.5, gt=0)
    """1-sigma localisation noise of a correspondence (px); propagates into SfmCloud.sigma_m.
    Half the KLT forward-backward gate (§II-B-1: 1 px)."""
    k_max_reprojection: float = bounded(4.0, gt=0)
    """Reprojection error gate in either image as a multiple of pixel_sigma_px (4 x 0.5 = 2 px)."""
    min_parallax_deg: float = bounded(0.5, ge=0, lt=90)
    """Minimum angle between the two viewing rays at the point (deg): at 0.5 deg and 0.5 px noise
    (f ~ 1100 px) depth sigma is already ~7 % of range. Simulated pairs have median 3.5-4.5 deg."""
    max_relative_sigma: float = bounded(0.05, gt=0)
    """Drop points whose predicted 1-sigma depth error exceeds this fraction of their range."""
    max_sigma_vs_fixation: float | None = bounded(1.3, gt=0)
    """Drop points whose sigma exceeds this multiple of the sigma of a point at the pair's fixation point
    (where the optical axes pass closest: what the orbiting camera looks at). The target's points lie at
    0.85-1.05 x it at 50-200 m. Depth sigma grows with the square of the range, so this keeps what lies up
    to ~1.14 x the fixation depth and everything nearer: at 0 deg obliquity the image reaches the horizon
    (points 700 m away, sigma of metres) and the matcher found noise keypoints there. Dense tuning set
    (240 scenes, 50 and 100 m): SHOT F1 0.911 -> 0.928, RoPS 0.886 -> 0.903; 200 m unchanged; the matcher
    about twice as fast (docs/sfm.md, "Points beyond the fixation point"). None: no such gate (and none
    when the axes do not converge)."""
    min_baseline_m: float = bounded(1e-3, ge=0)
    """Camera centres closer than this (m) make a zero-baseline pair: an empty cloud, reason given."""
    min_correspondences: int = bounded(5, ge=1)
    """Fewer correspondences than this give an empty cloud (nothing worth triangulating)."""

    # --- Frame pairing ---
    pair_gap_frames: int = bounded(1, ge=1)
    """Frames t and t + gap make a pair. With the simulator's frame interval (baseline 7.5 % of the
    range, ~4 deg parallax) gap 1 meets the accuracy goals at 50-200 m with the most points; larger
    gaps trade points for accuracy (measured table in docs/sfm.md)."""

    def __post_init__(self) -> None:
        """Validate; raise ConfigError naming the bad value."""
        if self.matcher not in ("gftt", "surf", "sgm"):
            raise ConfigError(f"matcher {self.matcher!r} must be 'gftt', 'surf' or 'sgm'")
        check_fields(self)
        if self.k_sgm_large_jump_penalty <= self.k_sgm_small_jump_penalty:
            raise ConfigError(
                f"k_sgm_large_jump_penalty {self.k_sgm_large_jump_penalty} must exceed "
                f"k_sgm_small_jump_penalty {self.k_sgm_small_jump_penalty}"
            )

    @property
    def max_reprojection_px(self) -> float:
        """Reprojection error gate (px) = k_max_reprojection x pixel_sigma_px."""
        return self.k_max_reprojection * self.pixel_sigma_px
