import numpy as np
import pytest

from atr.errors import ConfigError
from atr.sim.noise import NoiseSpec, noisy_cloud, noisy_image, parse_noise
from atr.sim.render import to_srgb8


@pytest.mark.parametrize(
    "spec,expected",
    [
        (None, NoiseSpec()),
        ("none", NoiseSpec()),
        ("shot", NoiseSpec(True, 0.0)),
        ("gaussian:10", NoiseSpec(False, 0.10)),
        ("gauss30", NoiseSpec(False, 0.30)),
        ("shot,gaussian:30cm", NoiseSpec(True, 0.30)),
    ],
)
def test_parse(spec, expected):
    assert parse_noise(spec) == expected


def test_parse_rejects_unknown():
    with pytest.raises(ConfigError):
        parse_noise("salt")


def test_gaussian_image_sigma_is_fraction_of_full_scale():
    lin = np.full((200, 200, 3), 0.2, np.float32)
    img = to_srgb8(lin)
    out = noisy_image(lin, img, NoiseSpec(False, 0.10), 600.0, np.random.default_rng(0))
    assert np.std(out.astype(float) - img) == pytest.approx(25.5, rel=0.05)


def test_shot_noise_is_poisson_on_linear_intensity():
    lin = np.full((300, 300, 3), 0.25, np.float32)
    img = to_srgb8(lin)
    out = noisy_image(lin, img, NoiseSpec(True, 0.0), 400.0, np.random.default_rng(0))
    assert out.dtype == np.uint8 and np.std(out.astype(float)) > 2.0
    assert abs(out.mean() - img.mean()) < 1.0  # unbiased in the mean (to rounding)


def test_lidar_gaussian_noise_in_metres():
    pts = np.zeros((20000, 3))
    out = noisy_cloud(
        pts + [0, 0, 100.0], np.zeros(3), NoiseSpec(False, 0.30), 1e-3, np.random.default_rng(0)
    )
    assert np.std(out - [0, 0, 100.0], axis=0) == pytest.approx([0.3, 0.3, 0.3], rel=0.05)


def test_nav_noise_gives_the_fix_gnss_ins_errors_where_the_settings_give_none():
    import dataclasses

    from atr.sim.config import SimConfig
    from atr.sim.noise import GNSS_INS_ERRORS, parse_noise, with_navigation_errors

    spec = parse_noise("shot,nav")
    assert spec.navigation and spec.shot and spec.active
    assert not parse_noise("nav").active  # images and LIDAR stay clean
    exact = SimConfig()
    assert not exact.nav_fix_noisy
    assert with_navigation_errors(exact, parse_noise("none")) is exact
    noisy = with_navigation_errors(exact, spec)
    assert noisy.nav_fix_noisy
    assert {n: getattr(noisy, n) for n in GNSS_INS_ERRORS} == GNSS_INS_ERRORS
    own = dataclasses.replace(exact, nav_heading_sigma_deg=2.0)  # a setting given is kept
    assert with_navigation_errors(own, spec).nav_heading_sigma_deg == 2.0
