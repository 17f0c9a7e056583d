"""Parameters of the 3D local descriptors: defaults, units and where each value comes from.

Geometric sizes are given as multiples of one scale: the description (support) radius R for the inner radii of a
descriptor, and the average resolution r of the CAD model for R itself (R = ρ·r, paper §III-B).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from atr.errors import ConfigError

DescriptorName = Literal["shot", "usc", "3dsc", "fpfh", "rops", "hod", "hod-s"]
DESCRIPTOR_NAMES: tuple[str, ...] = get_args(DescriptorName)

# Lengths with the default parameters (paper Table III). USC: PCL's layout 14 azimuth x 14 elevation x 10 radial
# = 1960; the paper (and Tombari et al. 2010, who reuse 3DSC's 12 x 11 x 15) says 1980, reachable with
# azimuth_bins=12, elevation_bins=11, radial_bins=15. See docs/features3d.md.
DESCRIPTOR_LENGTHS: dict[str, int] = {
    "shot": 352,
    "usc": 1960,
    "3dsc": 1980,
    "fpfh": 33,
    "rops": 135,
    "hod": 240,
    "hod-s": 40,
}


@dataclass(frozen=True)
class DescriptionRadius:
    """One row of the description-radius table: R = rho_mr × r (r = average CAD-model resolution, metres).

    Attributes:
        rho_mr: multiplier ρ of the mesh/cloud resolution (dimensionless, "mr" units).
        source: where ρ comes from.

    """

    rho_mr: float
    source: str


# Paper §III-B: "The description radius of each 3D descriptor was ρ·r, where r is the average point cloud
# resolution of the CAD model and ρ a multiplier as suggested by the authors of each descriptor (e.g. for HoD and
# HoD-S, r is the scene resolution)". The paper does not print the values; these are the authors' own choices as
# recalled. The descriptor papers' texts could not be consulted: every "paper" figure below is unverified. The PCL
# figures were checked: SHOT against PCL's test source (radius 20 × mr, mr = 0.002 m), USC and 3DSC against its
# test parameters transcribed in tests/data/pcl_oracles_features3d.json (0.04, 0.004, 0.008 m), RoPS's bins and
# rotations against PCL's ROPSEstimation defaults.
DESCRIPTION_RADII: dict[str, DescriptionRadius] = {
    "shot": DescriptionRadius(
        15.0,
        "Tombari, Salti, Di Stefano, ECCV 2010 and Salti et al., CVIU 2014: support radius 15 mr in the "
        "descriptor-matching experiments (unverified); PCL's SHOT test uses 20 mr (checked)",
    ),
    "usc": DescriptionRadius(
        20.0,
        "Tombari, Salti, Di Stefano, 3DOR 2010 (USC): radius 20 mr, minimal radius 0.1 R, density radius 0.2 R "
        "(unverified); PCL's USC test uses R = 20 mr, R/10 and R/5 (checked)",
    ),
    "3dsc": DescriptionRadius(
        20.0,
        "Frome et al., ECCV 2004 give absolute radii (r_min 0.1, r_max 2.5 scan units; unverified); 20 mr with "
        "r_min = R/10 and density radius R/5 as PCL's 3DSC test (checked) and Tombari et al. 2010's comparison "
        "(unverified)",
    ),
    "fpfh": DescriptionRadius(
        15.0,
        "Rusu et al., ICRA 2009 give no resolution multiple; 15 mr as in Guo et al., IJCV 2016, the comparison "
        "of local descriptors that the paper's descriptor set follows (unverified)",
    ),
    "rops": DescriptionRadius(
        15.0,
        "Guo et al., IJCV 2013 (RoPS): support radius 15 mr (unverified), 5 partition bins, 3 rotations "
        "(PCL's defaults, checked)",
    ),
    "hod": DescriptionRadius(
        15.0,
        "Kechagias-Stamatis & Aouf, HoD (2016): 15 x scene resolution (unverified; r is the scene resolution "
        "for HoD, paper §III-B)",
    ),
    "hod-s": DescriptionRadius(
        15.0, "Kechagias-Stamatis et al. 2017 (HoD-S): as HoD, 15 x scene resolution (unverified)"
    ),
}


def description_radius(name: str, resolution_m: float) -> float:
    """Description radius ρ·r of a descriptor, metres.

    Args:
        name: one of DESCRIPTOR_NAMES.
        resolution_m: average resolution r, metres (> 0): of the CAD model, or of the scene for HoD/HoD-S.

    Returns:
        The radius, metres.

    Raises:
        ConfigError: unknown name or resolution not > 0.

    """
    if name not in DESCRIPTION_RADII:
        raise ConfigError(f"descriptor {name!r} is not one of {DESCRIPTOR_NAMES}")
    if not resolution_m > 0:
        raise ConfigError(f"resolution {resolution_m} m must be > 0")
    return DESCRIPTION_RADII[name].rho_mr * resolution_m


@dataclass(frozen=True)
class NormalConfig:
    """Normal estimation by plane fit.

    Attributes:
        k_neighbours: neighbours of the plane fit, the point itself included (paper §II-B-2: "fitting a plane on
            the six closest neighbours").
        min_neighbours: fewer neighbours give a NaN normal (PCL: a plane needs 3 points).

    """

    k_neighbours: int = 6
    min_neighbours: int = 3

    def __post_init__(self) -> None:
        if self.k_neighbours < 3:
            raise ConfigError(f"k_neighbours {self.k_neighbours} must be >= 3")
        if self.min_neighbours < 3:
            raise ConfigError(f"min_neighbours {self.min_neighbours} must be >= 3")


@dataclass(frozen=True)
class ShotConfig:
    """SHOT (Tombari et al. 2010) as in PCL's SHOTEstimation.

    Attributes:
        shape_bins: cosine bins per spatial volume (PCL default 10; each volume stores shape_bins + 1 slots).
        min_neighbours: fewer neighbours in the radius (the point itself included) give a NaN row (PCL: 5).
        lrf_min_neighbours: fewer valid LRF neighbours (the point itself excluded) give a NaN frame (PCL: 5).

    """

    shape_bins: int = 10
    min_neighbours: int = 5
    lrf_min_neighbours: int = 5

    def __post_init__(self) -> None:
        if self.shape_bins < 2:
            raise ConfigError(f"shape_bins {self.shape_bins} must be >= 2")
        if self.min_neighbours < 1 or self.lrf_min_neighbours < 3:
            raise ConfigError(
                f"min_neighbours {self.min_neighbours} must be >= 1 and lrf_min_neighbours "
                f"{self.lrf_min_neighbours} >= 3"
            )


@dataclass(frozen=True)
class ShapeContextConfig:
    """3DSC (Frome et al. 2004) and USC (Tombari et al. 2010) binning, as in PCL.

    Attributes:
        azimuth_bins: azimuth sectors over 360°.
        elevation_bins: elevation sectors over 180° from the +z axis.
        radial_bins: log-spaced shells between minimal_radius and R.
        k_minimal_radius: minimal radius as a fraction of R (PCL tests: 0.004 for R = 0.04).
        k_point_density_radius: density radius as a fraction of R (PCL tests: 0.008 for R = 0.04).
        min_neighbours: fewer neighbours (the point itself included) give a NaN row. 5 as SHOT (PCL's 3DSC only
            needs 1, which is never limiting on real clouds; USC's LRF already needs 5 other points).
        seed: 3DSC's random x axis: PCL's mt19937 seed (12345 reproduces released PCL).

    """

    azimuth_bins: int
    elevation_bins: int
    radial_bins: int
    k_minimal_radius: float = 0.1
    k_point_density_radius: float = 0.2
    min_neighbours: int = 5
    seed: int = 12345

    def __post_init__(self) -> None:
        for name in ("azimuth_bins", "elevation_bins", "radial_bins"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} {getattr(self, name)} must be >= 1")
        if not 0 < self.k_minimal_radius < 1:
            raise ConfigError(f"k_minimal_radius {self.k_minimal_radius} must be in (0, 1)")
        if not self.k_point_density_radius > 0:
            raise ConfigError(f"k_point_density_radius {self.k_point_density_radius} must be > 0")

    @property
    def length(self) -> int:
        """Descriptor length = azimuth × elevation × radial bins."""
        return self.azimuth_bins * self.elevation_bins * self.radial_bins


# PCL's defaults: ShapeContext3DEstimation 12 x 11 x 15; UniqueShapeContext 14 x 14 x 10.
SC3D_DEFAULT = ShapeContextConfig(azimuth_bins=12, elevation_bins=11, radial_bins=15)
USC_DEFAULT = ShapeContextConfig(azimuth_bins=14, elevation_bins=14, radial_bins=10)


@dataclass(frozen=True)
class ShapeContextParams:
    """Per-call parameters of 3DSC and USC, with PCL's names; None takes the default from the config.

    Attributes:
        minimal_radius: first radial edge, metres (default ShapeContextConfig.k_minimal_radius · R).
        point_density_radius: metres (default ShapeContextConfig.k_point_density_radius · R).
        azimuth_bins: override of the config's azimuth sectors.
        elevation_bins: override of the config's elevation sectors.
        radial_bins: override of the config's radial shells.

    """

    minimal_radius: float | None = None
    point_density_radius: float | None = None
    azimuth_bins: int | None = None
    elevation_bins: int | None = None
    radial_bins: int | None = None


@dataclass(frozen=True)
class ShapeContext3dParams(ShapeContextParams):
    """Per-call parameters of 3DSC (PCL's ShapeContext3DEstimation).

    Attributes:
        seed: mt19937 seed of the random x axis (default ShapeContextConfig.seed = PCL's 12345).
        x_axis: "random" (released PCL) or "farthest" (PCL master, deterministic).

    """

    seed: int | None = None
    x_axis: Literal["random", "farthest"] = "random"

    def __post_init__(self) -> None:
        if self.x_axis not in ("random", "farthest"):
            raise ConfigError(f"x_axis {self.x_axis!r} must be 'random' or 'farthest'")


@dataclass(frozen=True)
class UscParams(ShapeContextParams):
    """Per-call parameters of USC (PCL's UniqueShapeContext).

    Attributes:
        lrf_radius: SHOT LRF radius, metres (default R).

    """

    lrf_radius: float | None = None
