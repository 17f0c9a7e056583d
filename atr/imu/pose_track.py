"""The pose track of one flight: IMU batches in, the camera's pose per frame and per frame pair out.

What services/pose_integrator does frame by frame and what the in-process evaluation does, in one object
(paper §II-B-1, eqs. 1-4). Each ImuBatch ends at a camera frame k; the track integrates it and gives the
frame's pose T_world_cam and, when frame k - gap has a pose, the pair (k - gap, k). A batch's `init` starts
a flight (no pose of frame k - gap yet) or, later, is an aided navigation fix at its frame: that frame's
pose is still the integrated one (the pair ending there used it) and the next pair starts from the fix.

The state is explicit and plain (`state_dict` / `from_state_dict`), so a service can checkpoint it after
every frame and a restarted process goes on exactly where the killed one stopped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from atr.errors import InputError
from atr.imu.config import ImuConfig
from atr.imu.strapdown import NavState, PoseIntegrator

STATE_VERSION = 1


@dataclass(frozen=True)
class FramePose:
    """The track's answer to one frame's IMU batch.

    Attributes:
        frame_seq: the frame k.
        stamp_ns: its stamp.
        T_world_cam: (4, 4) the camera pose integrated to the frame.
        frame_seq_t: the pair's first frame k - gap, or None when it has no pose (a flight's start).
        stamp_ns_t: that frame's stamp (None without a pair).
        T_world_cam_t: that frame's pose (None without a pair).

    """

    frame_seq: int
    stamp_ns: int
    T_world_cam: np.ndarray
    frame_seq_t: int | None = None
    stamp_ns_t: int | None = None
    T_world_cam_t: np.ndarray | None = None


class PoseTrack:
    """Camera poses of one flight from its IMU batches; one verb per frame (`add_batch`).

    Args:
        config: IMU settings.
        gap: frames between the two images of a pair (sfm.pair_gap_frames).

    """

    def __init__(self, config: ImuConfig, gap: int) -> None:
        self._config = config
        self._gap = int(gap)
        self._integrator: PoseIntegrator | None = None
        self._poses: dict[int, tuple[int, np.ndarray]] = {}  # frame_seq -> (stamp_ns, T_world_cam)
        self._last_frame: int | None = None
        self._lost: str | None = None  # why the track waits for a navigation fix
        self._last_answer: FramePose | None = None  # the last frame's pose and pair, as answered

    def add_batch(
        self,
        frame_seq: int,
        stamp_ns: int,
        t_ns: np.ndarray,
        gyro_radps: np.ndarray,
        accel_mps2: np.ndarray,
        init: NavState | None = None,
    ) -> FramePose | None:
        """Integrate the IMU batch that ends at frame `frame_seq`.

        Args:
            frame_seq: the frame k the batch ends at.
            stamp_ns: the frame's stamp, ns.
            t_ns: (N,) sample times, ns (N may be 0).
            gyro_radps: (N, 3) angular rates, rad/s.
            accel_mps2: (N, 3) specific forces, m/s^2.
            init: the batch's navigation state (a flight's start or an aided fix), if any.

        Returns:
            The frame's pose (and pair), or None for a repeated batch of a frame already done
            (a duplicate gets no second answer): a batch without `init` of a frame up to the last
            one, or the last batch again with its `init`.

        Raises:
            InputError: no initialisation yet, batches of earlier frames missing (the track then
                waits for the next navigation fix), or a bad batch.

        """
        frame, stamp = int(frame_seq), int(stamp_ns)
        if self._is_repeat(frame, stamp, init is not None):
            return None
        if init is not None and (self._integrator is None or frame != self._last_frame + 1):
            # a flight starts: the INS alignment before take-off, a fix after a lost track, or a new
            # flight's first batch; a fix at the next frame of this flight is an aided fix (below)
            self._integrator = PoseIntegrator(self._config, init)
            self._poses.clear()
            self._lost = None
            self._last_frame = None
            init = None
        if self._integrator is None:
            raise InputError(
                f"IMU batch for frame {frame} arrived "
                + (self._lost or "before any initialisation (`init`)")
            )
        if self._last_frame is not None and frame != self._last_frame + 1:
            self._lose(
                f"after the IMU batches of frames {self._last_frame + 1}..{frame - 1} were lost "
                "(the track waits for the next navigation fix, `init`)"
            )
            raise InputError(f"IMU batch for frame {frame} arrived {self._lost}")
        if len(t_ns):
            self._integrator.add_imu(np.asarray(t_ns, np.int64), gyro_radps, accel_mps2)
        T_world_cam = self._integrator.camera_pose(stamp)
        self._poses[frame] = (stamp, T_world_cam)
        self._last_frame = frame
        out = FramePose(frame, stamp, T_world_cam)
        if frame - self._gap in self._poses:
            stamp_t, T_world_cam_t = self._poses[frame - self._gap]
            out = FramePose(frame, stamp, T_world_cam, frame - self._gap, stamp_t, T_world_cam_t)
        if init is not None:
            # an aided navigation fix at this frame: the next pair starts from it
            self._integrator = PoseIntegrator(self._config, init)
            self._poses[frame] = (stamp, self._integrator.camera_pose(stamp))
        for old in [f for f in self._poses if f <= frame - self._gap]:
            del self._poses[old]
        self._last_answer = out
        return out

    def last_answer(self, frame_seq: int, stamp_ns: int) -> FramePose | None:
        """The answer given to frame `frame_seq` of stamp `stamp_ns`, if it was the last one: what a
        process restarted from a checkpoint puts again for a batch sent again (its predecessor may
        have died before its answer left).
        """
        last = self._last_answer
        if last is None or (last.frame_seq, last.stamp_ns) != (int(frame_seq), int(stamp_ns)):
            return None
        return last

    def _is_repeat(self, frame: int, stamp: int, has_init: bool) -> bool:
        if self._last_frame is None or frame > self._last_frame:
            return False
        if not has_init:
            return True
        # a batch with `init` of an earlier frame starts a new flight; only the last batch again
        # is a repeat
        return frame == self._last_frame and self._poses.get(frame, (None,))[0] == stamp

    def _lose(self, why: str) -> None:
        self._integrator, self._lost, self._last_frame = None, why, None
        self._poses.clear()

    # Checkpoints -------------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """The whole state as plain data (ints, strings, numpy arrays): what a checkpoint holds."""
        return {
            "version": STATE_VERSION,
            "gap": self._gap,
            "integrator": None if self._integrator is None else self._integrator.snapshot(),
            "poses": [[f, s, T] for f, (s, T) in sorted(self._poses.items())],
            "last_frame": self._last_frame,
            "lost": self._lost,
            "last_answer": None
            if self._last_answer is None
            else list(_answer_fields(self._last_answer)),
        }

    @classmethod
    def from_state_dict(cls, config: ImuConfig, state: dict[str, Any]) -> PoseTrack:
        """The track `state_dict` was taken of; it goes on exactly as the original would.

        Raises:
            InputError: the state is of another version.

        """
        if state.get("version") != STATE_VERSION:
            raise InputError(
                f"pose track state version {state.get('version')!r}, expected {STATE_VERSION}"
            )
        track = cls(config, int(state["gap"]))
        snapshot = state["integrator"]
        track._integrator = None if snapshot is None else PoseIntegrator.restore(config, snapshot)
        track._poses = {int(f): (int(s), np.array(T, np.float64)) for f, s, T in state["poses"]}
        last = state["last_frame"]
        track._last_frame = None if last is None else int(last)
        track._lost = state["lost"]
        answer = state.get("last_answer")
        track._last_answer = None if answer is None else _answer(answer)
        return track


def _answer_fields(pose: FramePose) -> tuple[Any, ...]:
    return (
        pose.frame_seq,
        pose.stamp_ns,
        pose.T_world_cam,
        pose.frame_seq_t,
        pose.stamp_ns_t,
        pose.T_world_cam_t,
    )


def _answer(fields: list[Any]) -> FramePose:
    frame, stamp, T, frame_t, stamp_t, T_t = fields
    return FramePose(
        int(frame),
        int(stamp),
        np.array(T, np.float64),
        None if frame_t is None else int(frame_t),
        None if stamp_t is None else int(stamp_t),
        None if T_t is None else np.array(T_t, np.float64),
    )


def nav_state(stamp_ns: int, init: dict[str, Any]) -> NavState:
    """The navigation state an ImuBatch's `init` field describes."""
    T = np.asarray(init["T_world_imu"], np.float64)
    return NavState(
        stamp_ns=stamp_ns,
        R_world_imu=T[:3, :3].copy(),
        p_world_m=T[:3, 3].copy(),
        v_world_mps=np.asarray(init["v_world_mps"], np.float64).copy(),
        gyro_bias_radps=np.asarray(init.get("gyro_bias_radps", np.zeros(3)), np.float64).copy(),
        accel_bias_mps2=np.asarray(init.get("accel_bias_mps2", np.zeros(3)), np.float64).copy(),
    )
