import json
from pathlib import Path

import numpy as np
import pytest

from atr.io.pcd import read_pcd, read_pcd_xyz

DATA = Path(__file__).resolve().parents[1] / "data"
SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"


@pytest.fixture(scope="session")
def bun0() -> np.ndarray:
    """PCL's descriptor test cloud, (397, 3) float64 (float32 values as stored)."""
    return read_pcd_xyz(DATA / "bun0.pcd")


@pytest.fixture(scope="session")
def bun0_fields() -> dict[str, np.ndarray]:
    return read_pcd(DATA / "bun0.pcd")


@pytest.fixture(scope="session")
def oracles() -> dict:
    return json.loads((DATA / "pcl_oracles_features3d.json").read_text())


@pytest.fixture(scope="session")
def bun0_normals(bun0) -> np.ndarray:
    from atr.features3d import estimate_normals

    return estimate_normals(bun0, radius=0.04)
