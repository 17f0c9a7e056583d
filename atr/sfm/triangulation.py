"""Triangulation of two-view correspondences with a known relative pose (paper §II-B-1).

The relative pose comes from the IMU (eq. 1), not from an essential matrix: with
T_cam_b_cam_a = inv(T_world_cam_b) @ T_world_cam_a, each correspondence is triangulated linearly
(``triangulate_linear`` on normalised coordinates) in camera a's frame, gated, and moved to the world.

Per-point uncertainty (SfmCloud.sigma_m): a pixel error of sigma_px is an angular error
sigma_theta = sigma_px / f on each ray. Turning one ray by d_theta slides the intersection along the
other ray by (range along the turned ray) * d_theta / sin(parallax). With independent errors on both
rays, sigma_m = sigma_theta * sqrt(range_a^2 + range_b^2) / sin(parallax). It is the 1-sigma error
along the viewing direction (the dominant, depth, component); the lateral error is smaller by about
sin(parallax). tests/sfm check it against a Monte-Carlo spread.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from atr.errors import InputError
from atr.sfm.config import SfmConfig

FIXATION_MAX_MISS_VS_BASELINE = 0.25
"""Optical axes that pass further apart than this multiple of the baseline fixate nothing the camera aims
at; an orbiting pair's pass within a tenth of it (``triangulate_known_pose``'s fixation gate)."""


@dataclass
class SfmCloud:
    """A sparse world-frame point cloud triangulated from one frame pair.

    Attributes:
        points_world_m: (N, 3) float64, metres, world frame (z up).
        sigma_m: (N,) float32, metres, 1-sigma depth uncertainty of each point.
        pixels: (N, 2) float32, pixel coordinates of each point in the first image (x right, y down),
            undistorted when reconstruct was given the lens's coefficients.
        stats: counters and figures of the run: "correspondences", "triangulated", "rejected_behind",
            "rejected_reprojection", "rejected_parallax", "rejected_sigma", "baseline_m", ... .
        reason: empty when the pair was processed; otherwise why the cloud is empty
            (e.g. "zero baseline 0.0 m < 0.001 m", "no keypoints in image a").

    """

    points_world_m: np.ndarray
    sigma_m: np.ndarray
    pixels: np.ndarray
    stats: dict[str, float | int] = field(default_factory=dict)
    reason: str = ""

    def __len__(self) -> int:
        return int(self.points_world_m.shape[0])

    @classmethod
    def empty(cls, reason: str, stats: dict[str, float | int] | None = None) -> SfmCloud:
        """An empty cloud that says why it is empty.

        Args:
            reason: human-readable cause, naming the value that made the pair unusable.
            stats: counters gathered before giving up.

        Returns:
            A cloud with zero points and the given reason.

        """
        return cls(
            points_world_m=np.zeros((0, 3), np.float64),
            sigma_m=np.zeros(0, np.float32),
            pixels=np.zeros((0, 2), np.float32),
            stats=dict(stats or {}),
            reason=reason,
        )


def validate_pose(T: np.ndarray, name: str) -> np.ndarray:
    """Check a 4x4 rigid transform and return it as float64.

    Args:
        T: (4, 4) homogeneous rigid transform.
        name: the argument's name, used in the error message.

    Returns:
        (4, 4) float64 copy of T.

    Raises:
        InputError: wrong shape, non-finite entries, a bottom row other than [0, 0, 0, 1], or a
            rotation block that is not orthonormal with determinant +1.

    """
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise InputError(f"{name} has shape {T.shape}, expected (4, 4)")
    if not np.all(np.isfinite(T)):
        raise InputError(f"{name} has non-finite entries: {T.tolist()}")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise InputError(f"{name} bottom row {T[3].tolist()} must be [0, 0, 0, 1]")
    R = T[:3, :3]
    # Tolerance allows float32 round trips through messages.
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0.0:
        raise InputError(f"{name} rotation block is not a proper rotation: {R.tolist()}")
    return T


def validate_intrinsics(K: np.ndarray) -> np.ndarray:
    """Check a pinhole camera matrix and return it as float64.

    Args:
        K: (3, 3) [[fx, s, cx], [0, fy, cy], [0, 0, 1]], pixels.

    Returns:
        (3, 3) float64 copy of K.

    Raises:
        InputError: wrong shape, non-finite entries, non-positive focal lengths, bad last row.

    """
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise InputError(f"K has shape {K.shape}, expected (3, 3)")
    if not np.all(np.isfinite(K)):
        raise InputError(f"K has non-finite entries: {K.tolist()}")
    if not (K[0, 0] > 0.0 and K[1, 1] > 0.0):
        raise InputError(f"K focal lengths fx={K[0, 0]}, fy={K[1, 1]} must be > 0")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0.0:
        raise InputError(
            f"K {K.tolist()} is not an upper-triangular pinhole matrix with K[2] = [0, 0, 1]"
        )
    return K


def validate_distortion(dist_coeffs: np.ndarray | None) -> np.ndarray | None:
    """Check OpenCV lens distortion coefficients; None when the lens is an ideal pinhole.

    Args:
        dist_coeffs: (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tx, ty]]]]) or None; an empty or
            all-zero vector means undistorted images.

    Returns:
        float64 coefficients, or None for a pinhole.

    Raises:
        InputError: a length OpenCV does not accept, or non-finite coefficients.

    """
    if dist_coeffs is None:
        return None
    dist = np.asarray(dist_coeffs, dtype=np.float64).ravel()
    if dist.size == 0:
        return None
    if dist.size not in (4, 5, 8, 12, 14):
        raise InputError(
            f"dist_coeffs has {dist.size} coefficients, expected 4, 5, 8, 12 or 14 (OpenCV order)"
        )
    if not np.all(np.isfinite(dist)):
        raise InputError(f"dist_coeffs has non-finite entries: {dist.tolist()}")
    return dist if np.any(dist) else None


def undistort_pixels(pixels: np.ndarray, K: np.ndarray, dist_coeffs: np.ndarray) -> np.ndarray:
    """Where each pixel of a distorted image would be through an ideal pinhole with the same K.

    Corners are found and tracked on the image as it came off the lens (local appearance barely
    changes); only their coordinates are corrected before triangulation, which is cheaper than
    remapping both images and keeps the paper's detector on the original pixels.

    Args:
        pixels: (N, 2) pixel coordinates in the distorted image.
        K: (3, 3) camera matrix.
        dist_coeffs: OpenCV distortion coefficients (validate_distortion).

    Returns:
        (N, 2) float32 pixel coordinates in the undistorted image.

    """
    if len(pixels) == 0:
        return np.zeros((0, 2), np.float32)
    undistorted = cv2.undistortPoints(
        np.asarray(pixels, np.float64).reshape(-1, 1, 2), K, dist_coeffs, None, None, K
    )
    return undistorted.reshape(-1, 2).astype(np.float32)


def _validate_pixels(pixels_a: np.ndarray, pixels_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(pixels_a, dtype=np.float64)
    b = np.asarray(pixels_b, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or b.shape != a.shape:
        raise InputError(
            f"pixels_a {a.shape} and pixels_b {b.shape} must both be (N, 2) with the same N"
        )
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InputError("pixels_a / pixels_b contain non-finite coordinates")
    return a, b


def relative_camera_pose(T_world_cam_a: np.ndarray, T_world_cam_b: np.ndarray) -> np.ndarray:
    """Camera b from camera a, R*_cam of eq. (1): inv(T_world_cam_b) @ T_world_cam_a.

    Args:
        T_world_cam_a: (4, 4) float64, world-from-camera at the first frame.
        T_world_cam_b: (4, 4) float64, world-from-camera at the second frame.

    Returns:
        (4, 4) float64 T_cam_b_cam_a: maps points in camera a's frame to camera b's frame.

    """
    return np.linalg.inv(T_world_cam_b) @ T_world_cam_a


def fixation_depth_m(
    T_world_cam_a: np.ndarray, T_world_cam_b: np.ndarray, max_miss_m: float = np.inf
) -> float | None:
    """Depth in camera a of the point where the two optical axes pass closest: what the camera fixates.

    A UAV that orbits its target and keeps it in view turns between frames so that the target stays
    in place in the image; the axes then cross near the target.

    Args:
        T_world_cam_a: (4, 4) world-from-camera at the first frame (OpenCV axes, z forward).
        T_world_cam_b: (4, 4) world-from-camera at the second frame.
        max_miss_m: axes that pass further apart than this do not fixate a point.

    Returns:
        The depth (m) along camera a's axis, or None when the axes are parallel, pass closest
        behind either camera, or miss each other by more than ``max_miss_m``.

    """
    axis_a, axis_b = T_world_cam_a[:3, 2], T_world_cam_b[:3, 2]
    offset = T_world_cam_a[:3, 3] - T_world_cam_b[:3, 3]
    cos_ab = float(axis_a @ axis_b)
    sin2 = 1.0 - cos_ab * cos_ab
    if sin2 < 1e-12:
        return None
    along_a, along_b = float(axis_a @ offset), float(axis_b @ offset)
    depth = (cos_ab * along_b - along_a) / sin2
    depth_b = (along_b - cos_ab * along_a) / sin2
    miss_m = float(np.linalg.norm(offset + depth * axis_a - depth_b * axis_b))
    return depth if depth > 0.0 and depth_b > 0.0 and miss_m <= max_miss_m else None


def predict_on_fixation_plane(
    pixels_a: np.ndarray,
    K: np.ndarray,
    dist_coeffs: np.ndarray | None,
    T_world_cam_a: np.ndarray,
    T_world_cam_b: np.ndarray,
    ground_z_m: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Where pixels of image a fall in image b if their points lie on the fixation plane.

    The fixation plane faces camera a at ``fixation_depth_m``. A pixel whose ray meets the ground
    (z = ``ground_z_m``) before that plane sees the foreground, not it.

    Args:
        pixels_a: (N, 2) pixels in image a, as they came off the lens.
        K: (3, 3) camera matrix.
        dist_coeffs: the lens's distortion coefficients, or None for a pinhole.
        T_world_cam_a: (4, 4) world-from-camera at image a.
        T_world_cam_b: (4, 4) world-from-camera at image b.
        ground_z_m: height of the ground in the world frame, metres.

    Returns:
        (N, 2) float32 predicted pixels in image b (through the same lens) and an (N,) bool mask of the
        pixels whose ray reaches the fixation plane above the ground; None when the optical axes do
        not converge in front of camera a (no fixation plane).

    """
    depth_m = fixation_depth_m(T_world_cam_a, T_world_cam_b)
    if depth_m is None or len(pixels_a) == 0:
        return None
    dist = np.zeros(4) if dist_coeffs is None else dist_coeffs
    normalised = cv2.undistortPoints(np.asarray(pixels_a, np.float64).reshape(-1, 1, 2), K, dist)
    rays_cam = np.c_[normalised.reshape(-1, 2), np.ones(len(pixels_a))]  # camera z = 1
    rays_world = rays_cam @ T_world_cam_a[:3, :3].T
    centre_a = T_world_cam_a[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth_to_ground = (ground_z_m - centre_a[2]) / rays_world[:, 2]
    reaches_plane = ~((rays_world[:, 2] < 0.0) & (depth_to_ground < depth_m))
    points_world = centre_a + rays_world * depth_m
    T_cam_b_world = np.linalg.inv(T_world_cam_b)
    rvec, _ = cv2.Rodrigues(T_cam_b_world[:3, :3])
    predicted, _ = cv2.projectPoints(points_world, rvec, T_cam_b_world[:3, 3], K, dist)
    return predicted.reshape(-1, 2).astype(np.float32), reaches_plane


def epipolar_distances_px(
    pixels_a: np.ndarray,
    pixels_b: np.ndarray,
    K: np.ndarray,
    dist_coeffs: np.ndarray | None,
    T_world_cam_a: np.ndarray,
    T_world_cam_b: np.ndarray,
) -> np.ndarray:
    """Distance of every pixel of image b from the epipolar line of every pixel of image a.

    The line comes from the known relative pose (eq. 1): F = K^-T [t]x R K^-1 on undistorted pixels.

    Args:
        pixels_a: (Na, 2) pixels in image a, as they came off the lens.
        pixels_b: (Nb, 2) pixels in image b, as they came off the lens.
        K: (3, 3) camera matrix.
        dist_coeffs: the lens's distortion coefficients, or None for a pinhole.
        T_world_cam_a: (4, 4) world-from-camera at image a.
        T_world_cam_b: (4, 4) world-from-camera at image b.

    Returns:
        (Na, Nb) float32 distances in (undistorted) pixels of image b.

    """
    T_ba = relative_camera_pose(T_world_cam_a, T_world_cam_b)
    t = T_ba[:3, 3]
    t_cross = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    K_inv = np.linalg.inv(K)
    F = K_inv.T @ t_cross @ T_ba[:3, :3] @ K_inv
    a, b = (
        (pixels_a, pixels_b)
        if dist_coeffs is None
        else (
            undistort_pixels(pixels_a, K, dist_coeffs),
            undistort_pixels(pixels_b, K, dist_coeffs),
        )
    )
    lines_b = np.c_[a, np.ones(len(a))] @ F.T  # l_b = F x_a
    lines_b /= np.hypot(lines_b[:, :1], lines_b[:, 1:2])  # unit normals: l . x is a distance
    # float32: a distance matrix of 4,000 x 4,000 keypoints, needed to ~0.01 px only.
    return np.abs(lines_b.astype(np.float32) @ np.c_[b, np.ones(len(b))].T.astype(np.float32))


def triangulate_known_pose(
    pixels_a: np.ndarray,
    pixels_b: np.ndarray,
    K: np.ndarray,
    T_world_cam_a: np.ndarray,
    T_world_cam_b: np.ndarray,
    config: SfmConfig,
) -> SfmCloud:
    """Triangulate correspondences with the known camera poses and gate the results.

    Args:
        pixels_a: (N, 2) float pixels in the first image.
        pixels_b: (N, 2) float pixels of the same scene points in the second image.
        K: (3, 3) camera matrix (pixels), the same camera for both images, no distortion.
        T_world_cam_a: (4, 4) world-from-camera (OpenCV camera axes) at the first image.
        T_world_cam_b: (4, 4) world-from-camera at the second image.
        config: gates (reprojection, parallax, relative sigma) and the pixel noise.

    Returns:
        The world-frame cloud of points that pass every gate, with per-point sigma. Empty, with a
        reason, for a zero-baseline pair or too few correspondences.

    Raises:
        InputError: malformed pixels, K or poses (shape, non-finite, not rigid).

    """
    a, b = _validate_pixels(pixels_a, pixels_b)
    K = validate_intrinsics(K)
    T_wa = validate_pose(T_world_cam_a, "T_world_cam_a")
    T_wb = validate_pose(T_world_cam_b, "T_world_cam_b")

    n = a.shape[0]
    baseline_m = float(np.linalg.norm(T_wb[:3, 3] - T_wa[:3, 3]))
    stats: dict[str, float | int] = {"correspondences": n, "baseline_m": baseline_m}
    if baseline_m < config.min_baseline_m:
        return SfmCloud.empty(
            f"zero baseline {baseline_m:.3g} m < min_baseline_m {config.min_baseline_m} m", stats
        )
    if n < config.min_correspondences:
        return SfmCloud.empty(
            f"{n} correspondences < min_correspondences {config.min_correspondences}", stats
        )

    T_ba = relative_camera_pose(T_wa, T_wb)
    X_a, X_b, finite = _triangulate_in_a(a, b, K, T_ba)
    in_front = finite & (X_a[:, 2] > 0.0) & (X_b[:, 2] > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        proj_a = (X_a @ K.T)[:, :2] / X_a[:, 2:3]
        proj_b = (X_b @ K.T)[:, :2] / X_b[:, 2:3]
    reproj_px = np.maximum(np.linalg.norm(proj_a - a, axis=1), np.linalg.norm(proj_b - b, axis=1))
    reproj_ok = reproj_px <= config.max_reprojection_px
    fixation_m = fixation_depth_m(T_wa, T_wb, max_miss_m=FIXATION_MAX_MISS_VS_BASELINE * baseline_m)
    depth = _depth_gates(X_a, K, T_ba, fixation_m, config)
    if depth.fixation_sigma_m is not None:
        stats["fixation_sigma_m"] = depth.fixation_sigma_m

    # Each rejected point is counted once, at the first gate it fails.
    keep = in_front & reproj_ok & depth.parallax_ok & depth.sigma_ok
    stats["rejected_behind"] = int(np.count_nonzero(~in_front))
    stats["rejected_reprojection"] = int(np.count_nonzero(in_front & ~reproj_ok))
    stats["rejected_parallax"] = int(np.count_nonzero(in_front & reproj_ok & ~depth.parallax_ok))
    stats["rejected_sigma"] = int(
        np.count_nonzero(in_front & reproj_ok & depth.parallax_ok & ~depth.sigma_ok)
    )
    stats["triangulated"] = int(np.count_nonzero(keep))
    if not np.any(keep):
        return SfmCloud.empty("no correspondence passed the triangulation gates", stats)
    stats["median_parallax_deg"] = float(np.rad2deg(np.median(depth.parallax_rad[keep])))
    stats["median_range_m"] = float(np.median(depth.range_m[keep]))
    stats["median_sigma_m"] = float(np.median(depth.sigma_m[keep]))
    points_world = X_a[keep] @ T_wa[:3, :3].T + T_wa[:3, 3]
    return SfmCloud(
        points_world_m=np.ascontiguousarray(points_world, dtype=np.float64),
        sigma_m=depth.sigma_m[keep].astype(np.float32),
        pixels=a[keep].astype(np.float32),
        stats=stats,
    )


def _triangulate_in_a(
    a: np.ndarray, b: np.ndarray, K: np.ndarray, T_ba: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each correspondence's point in camera a's frame and in camera b's, and which are finite
    (a non-finite point is set to the origin, so that it fails the in-front gate).
    """
    R_ba, t_ba = T_ba[:3, :3], T_ba[:3, 3]
    n = a.shape[0]
    K_inv = np.linalg.inv(K)
    rays_a = np.c_[a, np.ones(n)] @ K_inv.T  # normalised image coordinates, z = 1
    rays_b = np.c_[b, np.ones(n)] @ K_inv.T
    X_a = triangulate_linear(rays_a[:, :2], rays_b[:, :2], R_ba, t_ba)
    finite = np.all(np.isfinite(X_a), axis=1)
    X_a[~finite] = 0.0
    X_b = X_a @ R_ba.T + t_ba
    return X_a, X_b, finite


@dataclass(frozen=True)
class _DepthGates:
    """Parallax and depth uncertainty of each point, and the gates on them.

    Attributes:
        parallax_rad: (N,) angle between the two rays, radians.
        range_m: (N,) distance from camera a, metres.
        sigma_m: (N,) 1-sigma depth uncertainty, metres.
        parallax_ok: (N,) parallax >= min_parallax_deg.
        sigma_ok: (N,) sigma within max_relative_sigma of the range and, when set, within
            max_sigma_vs_fixation of the sigma at the fixation depth.
        fixation_sigma_m: sigma of a point on camera a's axis at the fixation depth, metres (None when
            not used).

    """

    parallax_rad: np.ndarray
    range_m: np.ndarray
    sigma_m: np.ndarray
    parallax_ok: np.ndarray
    sigma_ok: np.ndarray
    fixation_sigma_m: float | None


def _depth_gates(
    X_a: np.ndarray, K: np.ndarray, T_ba: np.ndarray, fixation_m: float | None, config: SfmConfig
) -> _DepthGates:
    """The parallax and sigma gates of points in camera a's frame (``triangulate_known_pose``)."""
    R_ba, t_ba = T_ba[:3, :3], T_ba[:3, 3]
    # Camera b's centre in camera a's frame is -R^T t.
    centre_b = -R_ba.T @ t_ba
    sigma_theta = config.pixel_sigma_px / (0.5 * (K[0, 0] + K[1, 1]))
    range_a = np.linalg.norm(X_a, axis=1)
    parallax_rad, sigma = _parallax_and_sigma(X_a, centre_b, sigma_theta)
    parallax_ok = parallax_rad >= np.deg2rad(config.min_parallax_deg)
    with np.errstate(invalid="ignore"):
        sigma_ok = sigma <= config.max_relative_sigma * range_a
    fixation_sigma_m = None
    if config.max_sigma_vs_fixation is not None and fixation_m is not None:
        _, sigma_fixation = _parallax_and_sigma(
            np.array([[0.0, 0.0, fixation_m]]), centre_b, sigma_theta
        )
        fixation_sigma_m = float(sigma_fixation[0])
        with np.errstate(invalid="ignore"):
            sigma_ok &= sigma <= config.max_sigma_vs_fixation * sigma_fixation[0]
    return _DepthGates(parallax_rad, range_a, sigma, parallax_ok, sigma_ok, fixation_sigma_m)


def triangulate_linear(
    normalised_a: np.ndarray, normalised_b: np.ndarray, R_ba: np.ndarray, t_ba: np.ndarray
) -> np.ndarray:
    """Linear two-view triangulation in camera a's frame (Hartley & Zisserman §12.2, inhomogeneous form).

    Each correspondence gives the four linear equations of the DLT, x P_3 - P_1 = 0 and y P_3 - P_2 = 0
    for P_a = [I | 0] and P_b = [R_ba | t_ba]; with the point's last coordinate set to 1 they are solved
    in the least-squares sense through their 3 x 3 normal equations, by Cramer's rule, for all points at
    once. ``cv2.triangulatePoints`` solves the homogeneous form with one SVD per point: the same point for
    rays that meet (1e-12 m apart); for rays that pixel noise makes miss, OpenCV's point lies ~230 x
    further from the truth than from ours at 0.5 px, ~120 x at 1 px (tests/sfm). Written here for speed:
    0.04-0.05 x OpenCV's time on a dense pair's correspondences (``bench/sfm.py``; docs/sfm.md,
    "Triangulation with the known pose").

    Args:
        normalised_a: (N, 2) normalised image coordinates (K^-1 x, z = 1) in camera a.
        normalised_b: (N, 2) the same points' normalised coordinates in camera b.
        R_ba: (3, 3) rotation of camera a's frame into camera b's.
        t_ba: (3,) translation of camera a's frame into camera b's.

    Returns:
        (N, 3) points in camera a's frame; rows of rays that meet nowhere (parallel) are not finite.

    """
    xa, ya = normalised_a[:, 0], normalised_a[:, 1]
    xb, yb = normalised_b[:, 0], normalised_b[:, 1]
    # The DLT's rows: (-1, 0, xa), (0, -1, ya), p = xb R_2 - R_0 and q = yb R_2 - R_1, with right-hand
    # sides 0, 0, u and v. The six entries of the symmetric A^T A and A^T b are written out, per point,
    # so that no (N, 3) temporary is made per product.
    p0, p1, p2 = (xb * R_ba[2, i] - R_ba[0, i] for i in range(3))
    q0, q1, q2 = (yb * R_ba[2, i] - R_ba[1, i] for i in range(3))
    u = t_ba[0] - xb * t_ba[2]
    v = t_ba[1] - yb * t_ba[2]
    c00 = 1.0 + p0 * p0 + q0 * q0
    c01 = p0 * p1 + q0 * q1
    c02 = p0 * p2 + q0 * q2 - xa
    c11 = 1.0 + p1 * p1 + q1 * q1
    c12 = p1 * p2 + q1 * q2 - ya
    c22 = xa * xa + ya * ya + p2 * p2 + q2 * q2
    b0, b1, b2 = p0 * u + q0 * v, p1 * u + q1 * v, p2 * u + q2 * v
    # Cramer's rule through the adjugate (symmetric too)
    a00 = c11 * c22 - c12 * c12
    a01 = c02 * c12 - c01 * c22
    a02 = c01 * c12 - c02 * c11
    a11 = c00 * c22 - c02 * c02
    a12 = c01 * c02 - c00 * c12
    a22 = c00 * c11 - c01 * c01
    det = c00 * a00 + c01 * a01 + c02 * a02
    with np.errstate(divide="ignore", invalid="ignore"):
        return (
            np.stack(
                [
                    a00 * b0 + a01 * b1 + a02 * b2,
                    a01 * b0 + a11 * b1 + a12 * b2,
                    a02 * b0 + a12 * b1 + a22 * b2,
                ],
                axis=1,
            )
            / det[:, None]
        )


def _parallax_and_sigma(
    X_a: np.ndarray, centre_b: np.ndarray, sigma_theta: float
) -> tuple[np.ndarray, np.ndarray]:
    """Parallax angle (rad) and 1-sigma depth error (m) of points seen from two camera centres.

    Args:
        X_a: (N, 3) points in camera a's frame (camera a's centre is the origin).
        centre_b: (3,) camera b's centre in camera a's frame.
        sigma_theta: angular error of each ray, rad (pixel sigma / focal length).

    """
    v_b = X_a - centre_b
    range_a = np.linalg.norm(X_a, axis=1)
    range_b = np.linalg.norm(v_b, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_par = np.einsum("ij,ij->i", X_a, v_b) / (range_a * range_b)
        parallax_rad = np.arccos(np.clip(np.nan_to_num(cos_par, nan=1.0), -1.0, 1.0))
        sigma = sigma_theta * np.sqrt(range_a**2 + range_b**2) / np.sin(parallax_rad)
    return parallax_rad, sigma
