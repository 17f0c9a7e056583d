"""Sensor noise of the paper's robustness tests (§III-D-6 shot noise, §III-D-7 Gaussian noise).

Noise spec strings (comma separated, case-insensitive): "none", "shot", "gaussian:10" (sigma in cm;
also "gauss:10", "gaussian10", "gaussian:10cm"). Example: "shot,gaussian:30".

What sigma in cm means for each sensor (the paper applies one sigma to both the images and the
LIDAR):
- LIDAR: zero-mean Gaussian noise with that standard deviation in metres on each coordinate of each
  point.
- Images: the same number read on the image's own scale, as a fraction of full scale: sigma = 10 cm
  gives Gaussian noise of 0.10 x 255 = 25.5 grey levels per channel, 30 cm gives 76.5 levels. (A
  metre-valued sigma has no direct meaning for pixels; reading 0.10 as 10 % of full scale is what an
  image-noise function taking the number 0.1 does, and keeps the two arms on the same numeric
  setting.)

Shot noise: images draw photo-electrons from a Poisson law (full_well electrons at full scale);
LIDAR ranges become q x Poisson(range / q) (paper eq. 8 in spirit: Poisson noise on the LIDAR
depth).

"nav" is not the paper's: the navigation fix (the INS alignment and, with `sim.nav_fix_every_frame`, every
aided fix) gets the errors of a small UAV's GNSS/INS, `GNSS_INS_ERRORS`, where the simulator's settings
give none: a sensitivity test of the premise that the camera's motion is known.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

import numpy as np

from atr.errors import ConfigError
from atr.sim.config import SimConfig


@dataclass(frozen=True)
class NoiseSpec:
    """Which noise to add.

    Attributes:
        shot: Poisson shot noise on images and LIDAR ranges.
        gaussian_sigma_m: Gaussian sigma, metres (0: none); images use it as a fraction of full
        scale.
        navigation: the navigation fix gets `GNSS_INS_ERRORS` (``with_navigation_errors``).

    """

    shot: bool = False
    gaussian_sigma_m: float = 0.0
    navigation: bool = False

    @property
    def active(self) -> bool:
        """True when the images or the LIDAR get noise."""
        return self.shot or self.gaussian_sigma_m > 0


GNSS_INS_ERRORS: dict[str, float] = {
    "nav_position_sigma_m": 1.5,
    "nav_altitude_sigma_m": 3.0,
    "nav_velocity_sigma_mps": 0.05,
    "nav_tilt_sigma_deg": 0.1,
    "nav_heading_sigma_deg": 0.5,
}
"""The "nav" noise: a single-antenna GNSS (no RTK) aiding a MEMS INS, as small UAVs carry: metre-level
position, centimetres per second of velocity, a tenth of a degree of tilt and half a degree of heading
(magnetometer-aided). SimConfig fields, applied where they are 0."""


def with_navigation_errors(config: SimConfig, noise: NoiseSpec) -> SimConfig:
    """The simulator settings a flight with ``noise`` runs on: `GNSS_INS_ERRORS` where the settings give
    none, when the noise asks for navigation errors.
    """
    if not noise.navigation:
        return config
    unset = {name: value for name, value in GNSS_INS_ERRORS.items() if getattr(config, name) == 0.0}
    return dataclasses.replace(config, **unset)


_GAUSS = re.compile(r"^gauss(?:ian)?:?(\d+(?:\.\d+)?)(cm)?$")


def parse_noise(spec: str | None) -> NoiseSpec:
    """Parse a noise spec string ("shot", "gaussian:10", "shot,gaussian:30", "none" or None).

    Raises:
        ConfigError: unknown token.

    """
    if spec is None:
        return NoiseSpec()
    shot, sigma, navigation = False, 0.0, False
    for token in (t.strip().lower() for t in spec.split(",")):
        if token in ("", "none"):
            continue
        if token in ("shot", "poisson"):
            shot = True
            continue
        if token == "nav":
            navigation = True
            continue
        m = _GAUSS.match(token)
        if m is None:
            raise ConfigError(
                f"noise spec token {token!r} must be 'shot', 'gaussian:<sigma cm>', 'nav' or 'none'"
            )
        sigma = float(m.group(1)) / 100.0
    return NoiseSpec(shot, sigma, navigation)


def noisy_image(
    img_linear: np.ndarray,
    srgb8: np.ndarray,
    spec: NoiseSpec,
    full_well: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Apply image noise; returns uint8 RGB.

    Args:
        img_linear: (H, W, 3) float32 linear intensities in [0, 1] (what the sensor integrates).
        srgb8: (H, W, 3) uint8 noise-free image.
        spec: noise to add.
        full_well: photo-electrons at full scale (shot noise strength).
        rng: generator.

    """
    from atr.sim.render import to_srgb8

    out = srgb8
    if spec.shot:
        electrons = rng.poisson(np.clip(img_linear, 0.0, 1.0) * full_well)
        out = to_srgb8((electrons / full_well).astype(np.float32))
    if spec.gaussian_sigma_m > 0:
        n = rng.normal(0.0, spec.gaussian_sigma_m * 255.0, out.shape)
        out = np.clip(out.astype(np.float64) + n, 0, 255).round().astype(np.uint8)
    return out


def noisy_cloud(
    points: np.ndarray,
    origin: np.ndarray,
    spec: NoiseSpec,
    quantum_m: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Apply LIDAR noise to (P, 3) world points seen from origin (3,); returns (P, 3) float64."""
    out = np.asarray(points, dtype=np.float64)
    if spec.shot and out.size:
        d = out - origin
        r = np.linalg.norm(d, axis=1)
        r_new = rng.poisson(r / quantum_m) * quantum_m
        out = origin + d * (r_new / np.maximum(r, 1e-9))[:, None]
    if spec.gaussian_sigma_m > 0:
        out = out + rng.normal(0.0, spec.gaussian_sigma_m, out.shape)
    return out
