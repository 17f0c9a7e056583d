"""Fixtures of the SfM tests; the scene builders live in sfm_scenes.py."""

from __future__ import annotations

import pytest
from sfm_scenes import PlaneScene, make_plane_scene


@pytest.fixture(scope="session")
def plane_scene() -> PlaneScene:
    return make_plane_scene()
