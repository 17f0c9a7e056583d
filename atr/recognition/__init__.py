"""3D ATR module (paper §II-A offline templates, §II-B-2 online matcher): pure functions on numpy arrays."""

from atr.recognition.config import DESCRIPTORS, RecognitionConfig
from atr.recognition.matcher import (
    STAGES,
    Detection,
    RecognitionResult,
    recognize,
    suppress_non_maxima,
)
from atr.recognition.steps import (
    Correspondences,
    Hypothesis,
    Verification,
    descriptor_sq_distances,
    filter_smooth_surfaces,
    group_geometrically_consistent,
    group_upright_hough,
    height_above_ground,
    knndr_from_distances,
    match_knndr,
    ransac_per_group,
    rigid_transform,
    uniform_subsample,
    upright_rigid_transform,
    verify_with_icp,
)
from atr.recognition.template import (
    Template,
    build_template,
    hidden_point_removal,
    sample_mesh_surface,
    template_from_points,
)

__all__ = [
    "DESCRIPTORS",
    "STAGES",
    "Correspondences",
    "Detection",
    "Hypothesis",
    "RecognitionConfig",
    "RecognitionResult",
    "Template",
    "Verification",
    "build_template",
    "filter_smooth_surfaces",
    "descriptor_sq_distances",
    "group_geometrically_consistent",
    "group_upright_hough",
    "height_above_ground",
    "knndr_from_distances",
    "hidden_point_removal",
    "match_knndr",
    "ransac_per_group",
    "recognize",
    "rigid_transform",
    "sample_mesh_surface",
    "suppress_non_maxima",
    "template_from_points",
    "uniform_subsample",
    "upright_rigid_transform",
    "verify_with_icp",
]
