"""The paper's scenario table (Table II) as presets.

| scenario | runs | obliquity          | range | LIDAR resolution | scenes with target / total |
|----------|------|--------------------|-------|------------------|----------------------------|
| 1        | 4    | 0, 15, 30, 45 deg  | 50 m  | 11 cm            | 334 / 345                  |
| 2        | 4    | 0, 15, 30, 45 deg  | 100 m | 18 cm            | 327 / 364                  |
| 3        | 1    | 30 deg             | 200 m | 30 cm            | 78 / 78                    |

Obliquity is the elevation angle of the line of sight from the target to the camera (0 deg: level
with the target, 90 deg: straight overhead). A scene is a frame pair (frame k, frame k+1), so a run
of n_scenes scenes has n_scenes + 1 frames. A scenario's scenes are split evenly over its runs.
"""

from __future__ import annotations

from dataclasses import dataclass

from atr.errors import ConfigError

# scenario -> (range m, obliquities of its runs in deg, LIDAR resolution m, scenes total, scenes
# with target)
TABLE_II: dict[int, tuple[float, tuple[float, ...], float, int, int]] = {
    1: (50.0, (0.0, 15.0, 30.0, 45.0), 0.11, 345, 334),
    2: (100.0, (0.0, 15.0, 30.0, 45.0), 0.18, 364, 327),
    3: (200.0, (30.0,), 0.30, 78, 78),
}


@dataclass(frozen=True)
class Scenario:
    """One run of one scenario of Table II.

    Attributes:
        scenario: scenario number (1, 2, 3).
        run: run number, 1-based.
        range_m: UAV-target slant range, metres.
        obliquity_deg: elevation angle of the line of sight to the target, degrees.
        n_scenes: scenes (frame pairs) in this run.
        lidar_resolution_m: LIDAR point spacing on the target, metres (Table II "resolution").
        absent_ratio: share of the scenario's scenes without the target (Table II).
        n_runs: runs in this scenario.
        absent_scenes: scenes of this run without the target: the scenario's Table II count split
            over its runs like the scenes.
        run_obliquities_deg: obliquities of every run of the scenario (the world keeps all their
        orbits clear).

    """

    scenario: int
    run: int
    range_m: float
    obliquity_deg: float
    n_scenes: int
    lidar_resolution_m: float
    absent_ratio: float
    n_runs: int
    run_obliquities_deg: tuple[float, ...]
    absent_scenes: int = 0

    @property
    def n_frames(self) -> int:
        """Frames in this run: one more than scenes (a scene is a pair of consecutive frames)."""
        return self.n_scenes + 1


def scenario(number: int, run: int) -> Scenario:
    """The Table II preset for a scenario number and a 1-based run number.

    Raises:
        ConfigError: unknown scenario or run.

    """
    if number not in TABLE_II:
        raise ConfigError(f"scenario {number} must be one of {sorted(TABLE_II)}")
    range_m, obliquities, resolution_m, total, with_target = TABLE_II[number]
    n_runs = len(obliquities)
    if not 1 <= run <= n_runs:
        raise ConfigError(f"run {run} of scenario {number} must be in 1..{n_runs}")
    per_run = [total // n_runs + (1 if i < total % n_runs else 0) for i in range(n_runs)]
    absent = total - with_target
    absent_per_run = [absent // n_runs + (1 if i < absent % n_runs else 0) for i in range(n_runs)]
    return Scenario(
        scenario=number,
        run=run,
        range_m=range_m,
        obliquity_deg=obliquities[run - 1],
        n_scenes=per_run[run - 1],
        lidar_resolution_m=resolution_m,
        absent_ratio=(total - with_target) / total,
        n_runs=n_runs,
        run_obliquities_deg=obliquities,
        absent_scenes=absent_per_run[run - 1],
    )


def all_scenarios() -> list[Scenario]:
    """Every run of every scenario of Table II, in order."""
    return [scenario(n, r) for n in sorted(TABLE_II) for r in range(1, len(TABLE_II[n][1]) + 1)]


def custom_scenario(
    range_m: float,
    obliquity_deg: float,
    n_scenes: int = 20,
    lidar_resolution_m: float | None = None,
) -> Scenario:
    """A single-run scenario outside Table II (scenario number 0), e.g. for tests and demos."""
    if range_m <= 0 or n_scenes <= 0 or not 0 <= obliquity_deg < 90:
        raise ConfigError(
            f"custom scenario needs range_m > 0 ({range_m}), n_scenes > 0 ({n_scenes}) and "
            f"obliquity in [0, 90) deg ({obliquity_deg})"
        )
    res = lidar_resolution_m if lidar_resolution_m is not None else 0.11 * range_m / 50.0
    return Scenario(
        0,
        1,
        float(range_m),
        float(obliquity_deg),
        int(n_scenes),
        float(res),
        0.0,
        1,
        (float(obliquity_deg),),
    )
