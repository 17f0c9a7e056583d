"""IMU pose integration: gyro + accelerometer samples -> IMU state -> camera pose (paper §II-B-1).

Two integrations, chosen by ImuConfig.integration:

- "strapdown": quaternion attitude from the bias-corrected gyro (third-order rotation vector per
  sample interval), specific force rotated into the world frame, gravity removed, velocity and
  position carried across frames. This is what the paper's eq. (4) needs to be right in flight.
- "paper": the literal eqs. (3)-(4): attitude angles integrated per axis and put through eq. (3);
  translation = double integral of the body-axis acceleration between two frames, from zero
  velocity, with no gravity term (right only when the vehicle starts each interval at rest and
  level... and even then gravity is integrated). Kept so the difference is measured, see
  docs/imu.md.

Measurements are taken as linear in time between samples; a frame time between two samples gets its
measurement by linear interpolation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from atr.errors import InputError
from atr.imu._kernels import paper_kernel, strapdown_kernel
from atr.imu.attitude import attitude_angles, attitude_matrix
from atr.imu.config import ImuConfig

_NS_PER_S = 1e9


@dataclass
class NavState:
    """Navigation state of the IMU at one instant.

    Attributes:
        stamp_ns: sensor time, int nanoseconds.
        R_world_imu: (3, 3) float64, world-from-IMU rotation (world z up).
        p_world_m: (3,) float64, IMU position in the world, metres.
        v_world_mps: (3,) float64, IMU velocity in the world, m/s.
        gyro_bias_radps: (3,) float64, gyro bias (subtracted from the raw rate), rad/s.
        accel_bias_mps2: (3,) float64, accelerometer bias (subtracted from the raw specific force),
            m/s^2.

    """

    stamp_ns: int
    R_world_imu: np.ndarray
    p_world_m: np.ndarray
    v_world_mps: np.ndarray
    gyro_bias_radps: np.ndarray
    accel_bias_mps2: np.ndarray

    def __post_init__(self) -> None:
        self.stamp_ns = int(self.stamp_ns)
        self.R_world_imu = _vector(self.R_world_imu, (3, 3), "R_world_imu")
        self.p_world_m = _vector(self.p_world_m, (3,), "p_world_m")
        self.v_world_mps = _vector(self.v_world_mps, (3,), "v_world_mps")
        self.gyro_bias_radps = _vector(self.gyro_bias_radps, (3,), "gyro_bias_radps")
        self.accel_bias_mps2 = _vector(self.accel_bias_mps2, (3,), "accel_bias_mps2")
        R = self.R_world_imu
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0.0:
            raise InputError(f"R_world_imu {R.tolist()} is not a rotation matrix")

    @classmethod
    def _trusted(cls, stamp_ns: int, R: np.ndarray, p: np.ndarray, v: np.ndarray, bg: np.ndarray,
                 ba: np.ndarray) -> NavState:  # fmt: skip
        """Build from arrays this module produced itself (float64, right shapes): no checks."""
        s = object.__new__(cls)
        s.stamp_ns, s.R_world_imu, s.p_world_m, s.v_world_mps = stamp_ns, R, p, v
        s.gyro_bias_radps, s.accel_bias_mps2 = bg, ba
        return s

    @property
    def T_world_imu(self) -> np.ndarray:
        """(4, 4) float64 world-from-IMU pose."""
        T = np.eye(4)
        T[:3, :3] = self.R_world_imu
        T[:3, 3] = self.p_world_m
        return T

    @classmethod
    def at_rest(cls, stamp_ns: int, T_world_imu: np.ndarray | None = None) -> NavState:
        """A state with zero velocity and zero biases at a given pose (identity if None)."""
        T = np.eye(4) if T_world_imu is None else np.asarray(T_world_imu, dtype=np.float64)
        return cls(stamp_ns, T[:3, :3], T[:3, 3], np.zeros(3), np.zeros(3), np.zeros(3))


def integrate(
    state: NavState,
    t_ns: np.ndarray,
    gyro_radps: np.ndarray,
    accel_mps2: np.ndarray,
    *,
    config: ImuConfig,
) -> NavState:
    """Propagate a navigation state through a batch of IMU samples.

    The measurement at state.stamp_ns is taken as the first sample (held back if t_ns[0] >
    stamp_ns); between samples it is linear in time.

    Args:
        state: state at state.stamp_ns.
        t_ns: (N,) int64 sample times, ns, strictly increasing, t_ns[0] >= state.stamp_ns.
        gyro_radps: (N, 3) float64 body angular rate in the IMU frame, rad/s.
        accel_mps2: (N, 3) float64 specific force in the IMU frame (gravity included, i.e. about +g
            up at rest), m/s^2.
        config: integration choice, gravity, gap limits.

    Returns:
        The state at t_ns[-1] (biases carried unchanged).

    Raises:
        InputError: empty batch, wrong shapes, NaN samples, non-increasing times, a sample before
            the state, or a gap longer than config.max_gap_samples periods.

    """
    t, gyro, accel = check_imu_samples(t_ns, gyro_radps, accel_mps2, config=config)
    if t[0] < state.stamp_ns:
        raise InputError(
            f"IMU sample t_ns[0] = {int(t[0])} ns is before the state's stamp {state.stamp_ns} ns"
        )
    _check_gap(state.stamp_ns, int(t[0]), config, "the state's stamp", "t_ns[0]")
    if t[0] > state.stamp_ns:
        t = np.concatenate(([state.stamp_ns], t))
        gyro = np.concatenate((gyro[:1], gyro))
        accel = np.concatenate((accel[:1], accel))
    return _propagate(state, t, gyro, accel, config)


def warm_up(config: ImuConfig) -> None:
    """Load the compiled integration kernel, on a few samples at rest. A process pays for it once, in
    its first frame otherwise: the pose_integrator service's first pose took 224 ms cold, the next
    ones 1-2 ms, and every scene queued behind it waited too.
    """
    t_ns = np.arange(3, dtype=np.int64) * int(round(config.sample_period_ns))
    accel_mps2 = np.tile(-np.asarray(config.gravity_world_mps2, np.float64), (3, 1))
    integrate(NavState.at_rest(0), t_ns, np.zeros((3, 3)), accel_mps2, config=config)


def check_imu_samples(
    t_ns: np.ndarray, gyro_radps: np.ndarray, accel_mps2: np.ndarray, *, config: ImuConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate an IMU batch and return it as (int64 (N,), float64 (N, 3), float64 (N, 3)) arrays.

    Raises:
        InputError: naming the first offending sample (empty, shape, NaN, order, gap).

    """
    t = np.asarray(t_ns)
    if t.ndim != 1 or t.shape[0] == 0:
        raise InputError(f"IMU batch t_ns must be a non-empty 1-D array, got shape {t.shape}")
    if not np.issubdtype(t.dtype, np.integer):
        raise InputError(f"IMU batch t_ns must be integer nanoseconds, got dtype {t.dtype}")
    t = t.astype(np.int64, copy=False)
    n = t.shape[0]
    gyro = np.asarray(gyro_radps, dtype=np.float64)
    accel = np.asarray(accel_mps2, dtype=np.float64)
    for name, a in (("gyro_radps", gyro), ("accel_mps2", accel)):
        if a.shape != (n, 3):
            raise InputError(f"{name} must have shape ({n}, 3) to match t_ns, got {a.shape}")
        if not np.isfinite(a).all():
            bad = ~np.all(np.isfinite(a), axis=1)
            i = int(np.argmax(bad))
            raise InputError(f"{name}[{i}] = {a[i].tolist()} at t_ns {int(t[i])} is not finite")
    if n > 1:
        dt = np.diff(t)
        if (dt <= 0).any():
            i = int(np.argmax(dt <= 0))
            raise InputError(
                f"IMU timestamps must be strictly increasing: t_ns[{i + 1}] = {int(t[i + 1])} ns "
                f"follows t_ns[{i}] = {int(t[i])} ns"
            )
        limit = config.max_gap_samples * config.sample_period_ns
        if (dt > limit).any():
            i = int(np.argmax(dt > limit))
            _check_gap(int(t[i]), int(t[i + 1]), config, f"t_ns[{i}]", f"t_ns[{i + 1}]")
    return t, gyro, accel


def _check_gap(t0_ns: int, t1_ns: int, config: ImuConfig, what0: str, what1: str) -> None:
    limit = config.max_gap_samples * config.sample_period_ns
    if t1_ns - t0_ns > limit:
        raise InputError(
            f"IMU gap of {(t1_ns - t0_ns) / 1e6:.3f} ms between {what0} ({t0_ns} ns) and {what1} "
            f"({t1_ns} ns) exceeds max_gap_samples {config.max_gap_samples} x "
            f"{config.sample_period_ns / 1e6:.3f} ms"
        )


def _propagate(
    state: NavState, t: np.ndarray, gyro: np.ndarray, accel: np.ndarray, config: ImuConfig
) -> NavState:
    """Integrate from t[0] == state.stamp_ns to t[-1]; gyro/accel: the measurement at every t."""
    if t.shape[0] == 1:
        return _copy(state)
    dt_s = np.diff(t).astype(np.float64) / _NS_PER_S
    n = t.shape[0]
    if config.integration == "strapdown":
        q_out = np.empty((n, 4))
        p_out = np.empty((n, 3))
        v_out = np.empty((n, 3))
        R = np.empty((3, 3))
        strapdown_kernel(
            state.R_world_imu, state.p_world_m, state.v_world_mps, state.gyro_bias_radps,
            state.accel_bias_mps2, config.gravity_world_mps2, dt_s, gyro, accel,
            q_out, p_out, v_out, R,
        )  # fmt: skip
        return NavState._trusted(int(t[-1]), R, p_out[-1], v_out[-1], state.gyro_bias_radps.copy(),
                                 state.accel_bias_mps2.copy())  # fmt: skip
    angles0 = np.array(attitude_angles(state.R_world_imu))
    angles = np.empty((n, 3))
    pos_body = np.empty((n, 3))
    vel_body = np.empty((n, 3))
    paper_kernel(angles0, state.gyro_bias_radps, state.accel_bias_mps2, dt_s, gyro, accel,
                 angles, pos_body, vel_body)  # fmt: skip
    R0 = state.R_world_imu
    return NavState._trusted(
        int(t[-1]),
        attitude_matrix(*angles[-1]),
        state.p_world_m + R0 @ pos_body[-1],
        R0 @ vel_body[-1],
        state.gyro_bias_radps.copy(),
        state.accel_bias_mps2.copy(),
    )


class PoseIntegrator:
    """Turns a stream of IMU batches into camera poses at frame times; one verb per input.

    Frames must come in time order. Each camera_pose call integrates from the previous frame (or the
    initial state) to the frame's stamp and makes that the new starting point. In "paper" mode this
    is exactly the paper's per-frame-pair window: eq. (4) starts every frame interval from zero
    velocity.

    Example:
        pi = PoseIntegrator(ImuConfig(), NavState.at_rest(t0_ns))
        pi.add_imu(t_ns, gyro_radps, accel_mps2)
        T_world_cam = pi.camera_pose(frame_stamp_ns)

    """

    def __init__(self, config: ImuConfig, initial: NavState) -> None:
        """Start from a known state (an initialisation message, alignment, or ground truth)."""
        self._config = config
        self._T_imu_cam = config.T_imu_cam_matrix
        self._state = _copy(initial)
        self._t = np.empty(0, dtype=np.int64)
        self._gyro = np.empty((0, 3))
        self._accel = np.empty((0, 3))
        self._first_sample_ns: int | None = None

    @property
    def config(self) -> ImuConfig:
        """The configuration in use."""
        return self._config

    @property
    def state(self) -> NavState:
        """The navigation state at the last frame (or the initial state), a copy."""
        return _copy(self._state)

    def add_imu(self, t_ns: np.ndarray, gyro_radps: np.ndarray, accel_mps2: np.ndarray) -> None:
        """Buffer an IMU batch (all samples since the last batch).

        Args:
            t_ns: (N,) int64 sample times, ns, strictly increasing and after the previous batch.
            gyro_radps: (N, 3) angular rate in the IMU frame, rad/s.
            accel_mps2: (N, 3) specific force in the IMU frame (gravity included), m/s^2.

        Raises:
            InputError: bad batch (see check_imu_samples), a batch not after the previous one, or a
                gap.

        """
        t, gyro, accel = check_imu_samples(t_ns, gyro_radps, accel_mps2, config=self._config)
        if self._t.shape[0]:
            last = int(self._t[-1])
            if t[0] <= last:
                raise InputError(
                    f"IMU batch starts at {int(t[0])} ns, not after the previous batch's last "
                    f"sample {last} ns"
                )
            _check_gap(last, int(t[0]), self._config, "the previous batch's last sample", "t_ns[0]")
        if self._first_sample_ns is None:
            self._first_sample_ns = int(t[0])
        self._t = np.concatenate((self._t, t))
        self._gyro = np.concatenate((self._gyro, gyro))
        self._accel = np.concatenate((self._accel, accel))
        self._drop_before(self._state.stamp_ns)

    def snapshot(self) -> dict[str, Any]:
        """The integrator's whole state as plain numpy data (a checkpoint); `restore` inverts it."""
        s = self._state
        return {
            "stamp_ns": s.stamp_ns,
            "R_world_imu": s.R_world_imu.copy(),
            "p_world_m": s.p_world_m.copy(),
            "v_world_mps": s.v_world_mps.copy(),
            "gyro_bias_radps": s.gyro_bias_radps.copy(),
            "accel_bias_mps2": s.accel_bias_mps2.copy(),
            "t_ns": self._t.copy(),
            "gyro_radps": self._gyro.copy(),
            "accel_mps2": self._accel.copy(),
            "first_sample_ns": self._first_sample_ns,
        }

    @classmethod
    def restore(cls, config: ImuConfig, snapshot: dict[str, Any]) -> PoseIntegrator:
        """The integrator a `snapshot` was taken of: it goes on exactly as the original would."""
        state = NavState._trusted(
            int(snapshot["stamp_ns"]),
            *(
                np.array(snapshot[name], np.float64)
                for name in (
                    "R_world_imu",
                    "p_world_m",
                    "v_world_mps",
                    "gyro_bias_radps",
                    "accel_bias_mps2",
                )
            ),
        )
        integrator = cls(config, state)
        integrator._t = np.array(snapshot["t_ns"], np.int64)
        integrator._gyro = np.array(snapshot["gyro_radps"], np.float64).reshape(-1, 3)
        integrator._accel = np.array(snapshot["accel_mps2"], np.float64).reshape(-1, 3)
        first = snapshot["first_sample_ns"]
        integrator._first_sample_ns = None if first is None else int(first)
        return integrator

    def camera_pose(self, stamp_ns: int) -> np.ndarray:
        """World-from-camera pose at a frame time; integrates up to the stamp.

        Args:
            stamp_ns: frame time, int ns, not before the previous frame.

        Returns:
            (4, 4) float64 T_world_cam = T_world_imu(stamp) · T_imu_cam.

        Raises:
            InputError: a stamp before the previous frame, before the first IMU sample, or more than
                config.max_extrapolation_samples periods after the last IMU sample.

        """
        stamp = int(stamp_ns)
        state = self._state
        if stamp == state.stamp_ns:
            return state.T_world_imu @ self._T_imu_cam
        if stamp < state.stamp_ns:
            raise InputError(
                f"frame stamp {stamp} ns is before the previous frame / initial state at "
                f"{state.stamp_ns} ns; frames must come in time order"
            )
        if self._first_sample_ns is None or stamp < self._first_sample_ns:
            first = (
                "none received" if self._first_sample_ns is None else f"{self._first_sample_ns} ns"
            )
            raise InputError(f"frame stamp {stamp} ns is before the first IMU sample ({first})")
        last = int(self._t[-1])
        max_extra = self._config.max_extrapolation_samples * self._config.sample_period_ns
        if stamp - last > max_extra:
            raise InputError(
                f"frame stamp {stamp} ns is {(stamp - last) / 1e6:.3f} ms after the last IMU "
                f"sample {last} ns (at most {max_extra / 1e6:.3f} ms allowed); send the IMU batch "
                "first"
            )
        t, gyro, accel = self._window(state.stamp_ns, stamp)
        self._state = _propagate(state, t, gyro, accel, self._config)
        self._drop_before(stamp)
        return self._state.T_world_imu @ self._T_imu_cam

    def _window(self, t0: int, t1: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Samples covering [t0, t1] with interpolated measurements at both ends."""
        ts = self._t
        inner = (ts > t0) & (ts < t1)
        g0, a0 = self._measurement_at(t0)
        g1, a1 = self._measurement_at(t1)
        if ts[0] > t0:  # initial state before the first sample: the first sample is held back
            _check_gap(t0, int(ts[0]), self._config, "the initial state", "the first IMU sample")
        t = np.concatenate(([t0], ts[inner], [t1]))
        gyro = np.vstack((g0, self._gyro[inner], g1))
        accel = np.vstack((a0, self._accel[inner], a1))
        return t, gyro, accel

    def _measurement_at(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        ts = self._t
        j = int(np.searchsorted(ts, t, side="right"))  # ts[j-1] <= t < ts[j]
        if j == 0:
            return self._gyro[0], self._accel[0]
        if j == ts.shape[0]:
            return self._gyro[-1], self._accel[-1]
        ta, tb = int(ts[j - 1]), int(ts[j])
        s = (t - ta) / (tb - ta)
        gyro = (1.0 - s) * self._gyro[j - 1] + s * self._gyro[j]
        accel = (1.0 - s) * self._accel[j - 1] + s * self._accel[j]
        return gyro, accel

    def _drop_before(self, t: int) -> None:
        """Forget samples no longer needed: keep the last one at or before t (for interpolation)."""
        j = int(np.searchsorted(self._t, t, side="right")) - 1
        if j > 0:
            self._t = self._t[j:]
            self._gyro = self._gyro[j:]
            self._accel = self._accel[j:]


def _copy(s: NavState) -> NavState:
    return NavState._trusted(s.stamp_ns, s.R_world_imu.copy(), s.p_world_m.copy(),
                             s.v_world_mps.copy(), s.gyro_bias_radps.copy(),
                             s.accel_bias_mps2.copy())  # fmt: skip


def _vector(x: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
    a = np.array(x, dtype=np.float64)
    if a.shape != shape:
        raise InputError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} {a.tolist()} is not finite")
    return a
