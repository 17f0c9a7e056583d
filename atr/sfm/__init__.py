"""Two-view structure from motion with a known (IMU) relative pose, paper §II-B-1.

Public surface: SfmConfig, reconstruct (the whole module, one call per frame pair), the two
correspondence schemes, known-pose triangulation, and our SURF.
"""

from atr.sfm.config import SfmConfig
from atr.sfm.correspondences import gftt_klt_correspondences, match_nndr, surf_correspondences
from atr.sfm.pipeline import reconstruct
from atr.sfm.surf import Surf
from atr.sfm.triangulation import SfmCloud, relative_camera_pose, triangulate_known_pose

__all__ = [
    "SfmCloud",
    "SfmConfig",
    "Surf",
    "gftt_klt_correspondences",
    "match_nndr",
    "reconstruct",
    "relative_camera_pose",
    "surf_correspondences",
    "triangulate_known_pose",
]
