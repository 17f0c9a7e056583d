import pytest

from atr.errors import ConfigError
from atr.sim import SimConfig, all_scenarios, scenario


def test_table_ii_scene_counts_and_geometry():
    runs = all_scenarios()
    assert len(runs) == 9
    totals = {s: sum(r.n_scenes for r in runs if r.scenario == s) for s in (1, 2, 3)}
    assert totals == {1: 345, 2: 364, 3: 78}
    assert [r.obliquity_deg for r in runs if r.scenario == 1] == [0.0, 15.0, 30.0, 45.0]
    assert scenario(3, 1).obliquity_deg == 30.0 and scenario(3, 1).range_m == 200.0
    assert scenario(2, 1).lidar_resolution_m == pytest.approx(0.18)
    assert scenario(1, 1).absent_ratio == pytest.approx(11 / 345)
    assert scenario(3, 1).absent_ratio == 0.0
    assert scenario(1, 1).n_frames == scenario(1, 1).n_scenes + 1
    absent = {s: sum(r.absent_scenes for r in runs if r.scenario == s) for s in (1, 2, 3)}
    assert absent == {1: 345 - 334, 2: 364 - 327, 3: 0}


@pytest.mark.parametrize("number,run", [(4, 1), (1, 0), (1, 5), (3, 2)])
def test_unknown_scenario_or_run_raises(number, run):
    with pytest.raises(ConfigError):
        scenario(number, run)


def test_frame_interval_gives_constant_parallax():
    cfg = SimConfig()
    for r in (50.0, 100.0, 200.0):
        dt = cfg.frame_interval_s(r)
        assert (dt * cfg.imu_rate_hz) == pytest.approx(round(dt * cfg.imu_rate_hz))
        assert cfg.speed_mps * dt / r == pytest.approx(cfg.baseline_to_range, rel=0.02)


def test_t72_spans_50_px_at_200_m():
    cfg = SimConfig()
    assert 6.9 * cfg.focal_px / 200.0 >= 50.0


def test_bad_config_raises():
    with pytest.raises(ConfigError):
        SimConfig(width_px=0)
    with pytest.raises(ConfigError):
        SimConfig(haze_visibility_m=-1.0)
