"""Classic 2D local-feature ATR, the paper's baseline (Fig. 3, Table IV)."""

from atr.baselines2d.config import PAIRS, Baseline2dConfig
from atr.baselines2d.detect import Detection2d, Result2d, ground_intersection, recognize_2d
from atr.baselines2d.features import Features2d, cap_keypoints, detect_and_describe, match_nndr
from atr.baselines2d.templates import (
    Template2d,
    TemplateView,
    crop_template_views,
    describe_templates,
    template_storage_bytes,
    viewing_azimuth_deg,
)

__all__ = [
    "PAIRS",
    "Baseline2dConfig",
    "Detection2d",
    "Features2d",
    "Result2d",
    "Template2d",
    "TemplateView",
    "cap_keypoints",
    "crop_template_views",
    "describe_templates",
    "detect_and_describe",
    "ground_intersection",
    "match_nndr",
    "recognize_2d",
    "template_storage_bytes",
    "viewing_azimuth_deg",
]
