"""The frame pairer of sfm: which camera frame is answered how, exactly once.

Images and relative poses (the pair (k - gap, k) from the pose integrator) arrive on two keys; the pairer
holds what a later pair can still use and says, per event, what frame k's one answer is:
- `Pair`: both images and the pose are here, reconstruct;
- `NoPartner`: frame k has no image k - gap (a flight's first frames, a flight whose first frame_seq is
  >= 1, a restarted process): an empty cloud with the reason;
- `Missing`: frame k's IMU batch never arrived, so no pose will come: an error.
A repeated image or pose of a frame already answered gives nothing (one answer per frame).

Images and IMU batches travel on different keys, and Zenoh runs different subscribers' callbacks
concurrently: an image may overtake its own frame's batch. So an image never decides that its batch is
missing. The evidence is a later frame's batch (one publisher's batches arrive in order: `add_imu`
answers the frames it skipped), or, when nothing later comes (lock-step sends the next frame only after
this one is answered), the caller's grace period (`give_up`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Pair:
    """Frame k's pair is complete: image_t (None when it was not accepted), image_t1, the pose."""

    frame_seq: int
    image_t: dict[str, Any] | None
    image_t1: dict[str, Any]
    pose: dict[str, Any]


@dataclass(frozen=True)
class NoPartner:
    """Frame k has no image k - gap: its answer is an empty cloud saying so."""

    frame_seq: int
    image: dict[str, Any]
    reason: str


@dataclass(frozen=True)
class Missing:
    """Frame k cannot get a pose: its answer is an error with this reason."""

    frame_seq: int
    reason: str


Answer = Pair | NoPartner | Missing


class FramePairer:
    """One answer per camera frame from the image, IMU and relative-pose streams.

    Args:
        gap: frames between the two images of a pair (sfm.pair_gap_frames).

    """

    def __init__(self, gap: int) -> None:
        self._gap = int(gap)
        self._images: dict[int, dict[str, Any]] = {}
        self._pairs: dict[int, dict[str, Any]] = {}
        self._seen: set[int] = set()  # frames whose image was accepted
        self._imu: set[int] = set()  # frames whose IMU batch arrived
        self._answered: set[int] = set()

    def answered(self, frame_seq: int) -> bool:
        """Whether frame `frame_seq` got its answer (a repeat of its inputs gets none)."""
        return int(frame_seq) in self._answered

    def add_image(self, frame_seq: int, image: dict[str, Any]) -> Answer | None:
        """Frame `frame_seq`'s image arrived; returns its answer when one is due now."""
        k, gap = int(frame_seq), self._gap
        if k in self._answered or k in self._images:
            return None
        self._seen.add(k)
        self._images[k] = image  # a later pair (k, k + gap) uses it
        self._prune(k - 4 * gap - 4)
        if k - gap not in self._seen:
            self._answered.add(k)
            return NoPartner(k, image, f"frame {k} has no partner {gap} frames earlier yet")
        return self._ready(k)

    def add_imu(self, frame_seq: int) -> list[Missing]:
        """Frame `frame_seq`'s IMU batch arrived (its pose will come, or the integrator reports it).

        Returns:
            The frames held for a pose whose batch was skipped (an earlier frame without one): their
            answers, now that a later batch proves theirs will not come.

        """
        j = int(frame_seq)
        self._imu.add(j)
        skipped = sorted(k for k in self._images if k < j and self.lacks_imu(k))
        return [m for m in (self.give_up(k) for k in skipped) if m is not None]

    def lacks_imu(self, frame_seq: int) -> bool:
        """Whether frame `frame_seq`'s image waits for a pose while its IMU batch has not arrived."""
        k = int(frame_seq)
        return k in self._images and k not in self._answered and k not in self._imu

    def give_up(self, frame_seq: int) -> Missing | None:
        """Frame `frame_seq`'s answer when its IMU batch is taken as lost (None if it came or the
        frame was answered meanwhile).
        """
        k = int(frame_seq)
        if not self.lacks_imu(k):
            return None
        self._answered.add(k)
        return Missing(k, f"no IMU batch of frame {k} arrived: no pose for it")

    def add_pair(self, pose: dict[str, Any]) -> Answer | None:
        """The relative pose of the pair (k - gap, k) arrived; returns frame k's answer when due."""
        k = int(pose["frame_seq_t1"])
        if k in self._answered:
            return None
        self._pairs[k] = pose
        return self._ready(k)

    def _ready(self, k: int) -> Answer | None:
        if k not in self._images or k not in self._pairs:
            return None
        pose = self._pairs.pop(k)
        self._answered.add(k)
        image_t = self._images.get(int(pose["frame_seq_t"]))
        pair = Pair(k, image_t, self._images[k], pose)
        # keep only the images a later pair can still use
        for old in [f for f in self._images if f <= k - self._gap]:
            del self._images[old]
        return pair

    def _prune(self, below: int) -> None:
        for held in (self._images, self._pairs):
            for f in [f for f in held if f < below]:
                del held[f]  # its pose never came (reported upstream)
        for kept in (self._seen, self._imu, self._answered):
            kept.difference_update([f for f in kept if f < below])
