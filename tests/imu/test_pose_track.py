"""The pose track: one answer per frame, a checkpoint that goes on exactly, lost batches reported."""

from __future__ import annotations

import numpy as np
import pytest

from atr.errors import InputError
from atr.imu import ImuConfig, NavState
from atr.imu.pose_track import PoseTrack
from bus import codec

PERIOD_NS = 50_000_000


def batch(
    frame: int, rng: np.random.Generator
) -> tuple[int, int, np.ndarray, np.ndarray, np.ndarray]:
    stamp = 1_000_000_000 + frame * PERIOD_NS
    t = stamp - PERIOD_NS + np.arange(1, 11, dtype=np.int64) * (PERIOD_NS // 10)
    gyro = 0.01 * rng.normal(size=(10, 3))
    accel = np.tile([0.0, 0.0, 9.80665], (10, 1)) + 0.1 * rng.normal(size=(10, 3))
    return frame, stamp, t, gyro, accel


def start(track: PoseTrack, rng: np.random.Generator, frame: int = 0):
    f, stamp, t, g, a = batch(frame, rng)
    return track.add_batch(f, stamp, t, g, a, NavState.at_rest(stamp - PERIOD_NS))


def test_a_restored_checkpoint_goes_on_exactly_as_the_original():
    rng = np.random.default_rng(1)
    batches = [batch(k, rng) for k in range(1, 8)]
    original = PoseTrack(ImuConfig(), gap=1)
    start(original, np.random.default_rng(0))
    for b in batches[:3]:
        original.add_batch(*b)
    saved = codec.unpack(codec.pack(original.state_dict()))  # as the service writes it
    restored = PoseTrack.from_state_dict(ImuConfig(), saved)
    for b in batches[3:]:
        a, r = original.add_batch(*b), restored.add_batch(*b)
        assert np.array_equal(a.T_world_cam, r.T_world_cam)
        assert np.array_equal(a.T_world_cam_t, r.T_world_cam_t) and a.frame_seq_t == r.frame_seq_t


def test_a_repeated_batch_gets_no_second_answer():
    rng = np.random.default_rng(2)
    track = PoseTrack(ImuConfig(), gap=1)
    start(track, rng)
    b1 = batch(1, rng)
    assert track.add_batch(*b1).frame_seq_t == 0
    assert track.add_batch(*b1) is None
    assert track.add_batch(*batch(2, rng)).frame_seq_t == 1


def test_a_flight_starting_at_a_later_frame_is_answered_without_a_pair():
    track = PoseTrack(ImuConfig(), gap=1)
    first = start(track, np.random.default_rng(3), frame=5)
    assert first.frame_seq == 5 and first.frame_seq_t is None


@pytest.mark.parametrize("gap", [1, 2, 3])
def test_a_navigation_fix_at_every_frame_pairs_frames_gap_apart(gap: int):
    # the evaluation's SfM arms fix the navigation at every frame; with pairs two or three frames
    # apart the fix at frame k must not start a new flight because frame k - gap has no pose yet
    rng = np.random.default_rng(4)
    track = PoseTrack(ImuConfig(), gap=gap)
    answers = []
    for k in range(8):
        f, stamp, t, g, a = batch(k, rng)
        answers.append(track.add_batch(f, stamp, t, g, a, NavState.at_rest(stamp)))
    assert [p.frame_seq_t for p in answers] == [None] * gap + list(range(8 - gap))


def test_lost_batches_are_reported_until_the_next_navigation_fix():
    rng = np.random.default_rng(4)
    track = PoseTrack(ImuConfig(), gap=1)
    start(track, rng)
    track.add_batch(*batch(1, rng))
    with pytest.raises(InputError, match=r"frames 2\.\.2 were lost"):
        track.add_batch(*batch(3, rng))
    with pytest.raises(InputError, match="lost"):
        track.add_batch(*batch(4, rng))
    f, stamp, t, g, a = batch(5, rng)
    assert track.add_batch(f, stamp, t, g, a, NavState.at_rest(stamp)).frame_seq == 5
    assert track.add_batch(*batch(6, rng)).frame_seq_t == 5


def test_a_repeated_batch_with_a_navigation_fix_is_a_repeat_but_an_earlier_fix_a_new_flight():
    rng = np.random.default_rng(5)
    track = PoseTrack(ImuConfig(), gap=1)
    f, stamp, t, g, a = batch(0, rng)
    fix = NavState.at_rest(stamp - PERIOD_NS)
    assert track.add_batch(f, stamp, t, g, a, fix) is not None
    assert track.add_batch(f, stamp, t, g, a, fix) is None  # the same batch sent again
    b1 = batch(1, rng)
    fix1 = NavState.at_rest(b1[1])  # an aided navigation fix at frame 1
    assert track.add_batch(*b1, fix1).frame_seq_t == 0
    assert track.add_batch(*b1, fix1) is None  # a repeat of the last batch, `init` included
    again = track.add_batch(f, stamp, t, g, a, fix)  # frame 0 again: a new flight starts
    assert again is not None and again.frame_seq_t is None


def test_a_process_restored_after_its_last_batch_can_answer_that_batch_again():
    """Killed after its checkpoint and before its answer left: the restored track knows the batch
    (no second integration) and still holds the answer to put again, identical."""
    rng = np.random.default_rng(3)
    track = PoseTrack(ImuConfig(), gap=1)
    start(track, rng)
    b1 = batch(1, rng)
    answer = track.add_batch(*b1)
    saved = codec.unpack(codec.pack(track.state_dict()))
    restored = PoseTrack.from_state_dict(ImuConfig(), saved)
    assert restored.add_batch(*b1) is None
    again = restored.last_answer(b1[0], b1[1])
    assert again is not None and again.frame_seq_t == answer.frame_seq_t == 0
    assert np.array_equal(again.T_world_cam, answer.T_world_cam)
    assert np.array_equal(again.T_world_cam_t, answer.T_world_cam_t)
    assert restored.last_answer(0, b1[1]) is None  # only the last frame's
