"""The frame pairer answers each camera frame exactly once."""

from __future__ import annotations

from atr.sfm.pairing import FramePairer, Missing, NoPartner, Pair


def pose(k: int, gap: int = 1) -> dict:
    return {"frame_seq_t": k - gap, "frame_seq_t1": k}


def test_each_frame_gets_one_answer_whatever_the_order_and_repeats():
    p = FramePairer(gap=1)
    for k in range(3):
        p.add_imu(k)
    assert isinstance(p.add_image(0, {"n": 0}), NoPartner)
    assert p.add_image(1, {"n": 1}) is None  # waits for its pose
    answer = p.add_pair(pose(1))
    assert isinstance(answer, Pair) and answer.image_t == {"n": 0}
    assert p.add_pair(pose(1)) is None and p.add_image(1, {"n": 1}) is None  # repeats
    assert p.add_pair(pose(2)) is None  # the pose before the image
    assert isinstance(p.add_image(2, {"n": 2}), Pair)


def test_a_flight_whose_first_frame_is_not_zero_is_answered():
    p = FramePairer(gap=1)
    p.add_imu(7)
    answer = p.add_image(7, {})
    assert isinstance(answer, NoPartner) and answer.frame_seq == 7


def test_an_image_that_overtakes_its_imu_batch_is_not_called_missing():
    """Images and batches come on different keys: the image may arrive first. That alone says
    nothing; the batch and the pose that follow give the frame its pair."""
    p = FramePairer(gap=1)
    p.add_imu(0)
    p.add_image(0, {})
    assert p.add_image(1, {}) is None and p.lacks_imu(1)
    assert p.add_imu(1) == [] and not p.lacks_imu(1)
    assert isinstance(p.add_pair(pose(1)), Pair)


def test_a_frame_whose_imu_batch_never_arrived_is_answered_with_an_error():
    p = FramePairer(gap=1)
    p.add_imu(0)
    p.add_image(0, {})
    assert p.add_image(1, {}) is None  # its batch may still come
    (answer,) = p.add_imu(2)  # a later batch: frame 1's was skipped
    assert isinstance(answer, Missing) and answer.frame_seq == 1
    assert "no IMU batch of frame 1" in answer.reason
    assert p.add_pair(pose(1)) is None and p.give_up(1) is None  # answered once


def test_a_caller_gives_up_on_a_batch_that_never_comes():
    """Lock-step sends nothing later until the frame is answered: the caller's grace decides."""
    p = FramePairer(gap=1)
    p.add_imu(0)
    p.add_image(0, {})
    p.add_image(1, {})
    answer = p.give_up(1)
    assert isinstance(answer, Missing) and p.answered(1)
    assert p.give_up(0) is None  # frame 0 was answered (no partner)


def test_answered_tells_a_repeat_of_an_answered_frame_from_one_still_waiting():
    p = FramePairer(1)
    p.add_image(0, {"n": 0})
    p.add_image(1, {"n": 1})
    assert p.answered(0) and not p.answered(1)  # frame 1 waits for its pose
    p.add_pair(pose(1))
    assert p.answered(1)
