"""Fixtures of the recognition tests. (pytest runs in importlib mode: tests reach these through fixtures.)"""

from collections.abc import Callable

import numpy as np
import pytest

from atr.recognition import HoughSettings, YawWindow, group_upright_hough


def _hough(scene, heights, model, corr, yaw_centre_rad=None, yaw_half_width_rad=np.pi, **kw):
    window = None if yaw_centre_rad is None else YawWindow(yaw_centre_rad, yaw_half_width_rad)
    return group_upright_hough(scene, heights, model, corr, HoughSettings(**kw), window)


@pytest.fixture(scope="session")
def hough() -> Callable[..., list[np.ndarray]]:
    """``group_upright_hough`` with its settings and heading window given as keywords (the reference's)."""
    return _hough
