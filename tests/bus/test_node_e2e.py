"""The service runtime over a real Zenoh bus: other processes, real sessions on loopback, multicast off."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import zenoh

from bus import codec
from bus.node import Node
from bus.session import open_session

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "schemas"))
from _procs import atr  # noqa: E402
from _publish_examples import KEYS  # noqa: E402
from conftest import REPO, bus_env, free_port, peer_config, stop_process, wait_for_port  # noqa: E402
from test_codec import assert_same, example  # noqa: E402

pytestmark = pytest.mark.e2e


def test_every_message_type_round_trips_between_processes(hub):
    with Node("receiver", "uav9", list(KEYS.values()), zenoh_config=peer_config(hub)) as node:
        child = subprocess.Popen(
            [sys.executable, str(HERE / "_publish_examples.py"), hub, "1.5"],
            env=bus_env(hub),
            cwd=REPO,
        )
        got = {}
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and len(got) < len(KEYS):
            for message in node.events(timeout_s=0.5):
                if message.source and message.source.startswith("examples@"):
                    got[message.type_name] = message.data
        child.wait(10)
    assert set(got) == set(KEYS)
    for name, data in got.items():
        assert_same(example(name), data)


def test_urgent_inputs_go_ahead_of_the_inputs_queued_before_them(hub):
    """The sfm's guidance: a service that has fallen behind handles it before the images queued."""
    urgent = KEYS["SearchGuidance"]
    with Node(
        "receiver", "uav9", list(KEYS.values()), zenoh_config=peer_config(hub), urgent=[urgent]
    ) as node:
        child = subprocess.Popen(
            [sys.executable, str(HERE / "_publish_examples.py"), hub, "1.5"],
            env=bus_env(hub),
            cwd=REPO,
        )
        child.wait(20)  # everything is queued before the service asks for its first input
        order = [
            m.type_name
            for m in node.events(timeout_s=0.5)
            if m.source and m.source.startswith("examples@")
        ]
    # published eighth of thirteen; the others in arrival order, which differs between keys
    assert order[0] == "SearchGuidance"
    assert sorted(order[1:]) == sorted(name for name in KEYS if name != "SearchGuidance")


def test_a_restarted_node_handles_again_the_input_a_killed_one_had_in_hand(hub, tmp_path):
    """The in-flight journal: a camera image in hand when the process died comes first, byte for byte."""
    image = KEYS["Image"]
    config = peer_config(hub)
    with Node("receiver", "uav9", [image], zenoh_config=config, state_dir=tmp_path) as first:
        child = subprocess.Popen(
            [sys.executable, str(HERE / "_publish_examples.py"), hub, "1.5"],
            env=bus_env(hub),
            cwd=REPO,
        )
        child.wait(20)
        in_hand = next(first.events(timeout_s=5))
        # the first process is still inside its handler: a second one starts as after a kill
        with Node(
            "receiver", "uav9", [image], zenoh_config=config, state_dir=tmp_path, replay_lost=True
        ) as second:
            again = next(second.events(timeout_s=1))
    assert in_hand.type_name == again.type_name == "Image"
    assert again.key == image
    assert_same(in_hand.data, again.data)
    assert_same(example("Image"), again.data)


def _collect(session: zenoh.Session, key: str) -> list[dict]:
    """The messages that arrive on `key` from now on, decoded, in arrival order."""
    found: list[dict] = []
    session.declare_subscriber(key, lambda s: found.append(codec.unpack(s.payload.to_bytes())))
    return found


def _collect_by(session: zenoh.Session, key: str, field: str) -> dict[int, dict]:
    """The last message on `key` per value of its `field` (e.g. frame_seq), from now on."""
    found: dict[int, dict] = {}
    session.declare_subscriber(
        key, lambda s: found.update({(m := codec.unpack(s.payload.to_bytes()))[field]: m})
    )
    return found


def _wait_running(session: zenoh.Session, service: str, timeout_s: float = 120) -> dict:
    found: list[dict] = []
    sub = session.declare_subscriber(
        f"atr/uav1/{service}/status", lambda s: found.append(codec.unpack(s.payload.to_bytes()))
    )
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            running = [s for s in found if s["state"] == "running"]
            if running:
                return running[-1]
            time.sleep(0.1)
    finally:
        sub.undeclare()
    raise TimeoutError(f"{service} not running after {timeout_s} s")


@contextmanager
def _service(
    hub: str, name: str, *args: str
) -> Iterator[tuple[subprocess.Popen[bytes], zenoh.Session]]:
    """`atr service NAME ARGS` on the hub's bus, running; yields it and a test session on the bus."""
    service = atr(hub, "service", name, *args)
    session = open_session(peer_config(hub))
    try:
        _wait_running(session, name)
        yield service, session
    finally:
        session.close()
        stop_process(service)


@contextmanager
def _up_pose_integrator(tmp_path: Path, *args: str) -> Iterator[zenoh.Session]:
    """`atr up` of a hub and a pose_integrator taking `args`; yields a session on its bus, then stops
    the layout, which must exit 0."""
    port = free_port()
    hub = f"tcp/127.0.0.1:{port}"
    layout = tmp_path / "mini.yml"
    layout.write_text(
        f"name: mini\nvariables: {{uav: uav1, hub: '{hub}'}}\n"
        "zenoh: compose/zenoh/local.json5\n"
        "processes:\n  - {name: router, service: router, role: hub, args: [--listen, '${hub}']}\n"
        f"  - {{name: pose_integrator, service: pose_integrator, args: [{', '.join(args)}]}}\n"
    )
    up = atr(hub, "up", str(layout))
    try:
        wait_for_port(port, 30)
        session = open_session(peer_config(hub))
        try:
            yield session
        finally:
            session.close()
    finally:
        assert stop_process(up, 30) == 0


def _kill_and_wait_restart(session: zenoh.Session, first: dict) -> dict:
    """kill -9 the pose_integrator whose running Status is `first`; the Status of the restarted one."""
    subprocess.run(["kill", "-9", str(first["pid"])], check=True)
    deadline = time.monotonic() + 60
    second = first
    while second["pid"] == first["pid"] and time.monotonic() < deadline:
        second = _wait_running(session, "pose_integrator", 60)
    assert second["pid"] != first["pid"]
    return second


def _good_imu(seq: int) -> dict:
    t = 1_000_000_000 + np.arange(1, 21, dtype=np.int64) * 5_000_000
    return {
        "stamp_ns": int(t[-1]),
        "seq": seq,
        "version": 1,
        "frame_seq": seq,
        "t_ns": t,
        "gyro_radps": np.zeros((20, 3)),
        "accel_mps2": np.tile([0.0, 0.0, 9.80665], (20, 1)),
        "init": {"T_world_imu": np.eye(4), "v_world_mps": np.zeros(3)},
    }


def test_bad_inputs_are_reported_and_the_next_good_one_is_processed(hub):
    with _service(hub, "pose_integrator") as (service, session):
        errors = _collect(session, "atr/uav1/pose_integrator/errors")
        poses = _collect(session, "atr/uav1/pose/camera")
        time.sleep(0.5)
        good = _good_imu(0)
        bad = [
            b"this is not msgpack \xc1",
            codec.pack({"stamp_ns": 1, "seq": 0}),  # breaks the schema: required fields missing
            codec.pack(good | {"gyro_radps": np.zeros((20, 3), np.float32)}),  # wrong dtype
            codec.pack(good | {"accel_mps2": np.full((20, 2), 1.0)}),  # wrong shape
            codec.pack(good | {"accel_mps2": np.full((20, 3), np.nan)}),  # NaN-filled
            b"\x00" * (codec.MAX_MESSAGE_BYTES + 16),  # oversized
        ]
        block = zenoh.CongestionControl.BLOCK
        for payload in bad:
            session.put("atr/uav1/imu", payload, congestion_control=block)
        session.put("atr/uav1/imu", codec.pack(good), congestion_control=block)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (len(errors) >= len(bad) and poses):
            time.sleep(0.1)
        assert len(errors) == len(bad), [e["reason"] for e in errors]
        assert all(e["service"] == "pose_integrator" and e["key"] == "atr/uav1/imu" for e in errors)
        reasons = " | ".join(e["reason"] for e in errors)
        for expected in ("not valid msgpack", "dtype", "shape", "NaN", "exceeds"):
            assert expected in reasons
        assert len(poses) == 1 and poses[0]["frame_seq"] == 0
        assert service.poll() is None  # still alive


def test_pose_integrator_applies_a_later_init_as_a_navigation_fix(hub):
    """sim.nav_fix_every_frame: a batch's `init` after the first is a fix at its frame; that frame's pose
    is still integrated (the pair ending there used it) and the next pair starts from the fix."""
    with _service(hub, "pose_integrator") as (_, session):
        poses = _collect_by(session, "atr/uav1/pose/camera", "frame_seq")
        pairs = _collect_by(session, "atr/uav1/pose/relative", "frame_seq_t")
        time.sleep(0.5)
        jumped = np.eye(4)
        jumped[:3, 3] = [5.0, 0.0, 0.0]
        for seq in range(3):
            batch = _good_imu(seq)
            batch["t_ns"] = batch["t_ns"] + seq * 100_000_000
            batch["stamp_ns"] = int(batch["t_ns"][-1])
            if seq == 1:  # a fix 5 m away from where the IMU says the vehicle is
                batch["init"] = {"T_world_imu": jumped, "v_world_mps": np.zeros(3)}
            elif seq == 2:
                del batch["init"]
            session.put(
                "atr/uav1/imu", codec.pack(batch), congestion_control=zenoh.CongestionControl.BLOCK
            )
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (len(poses) == 3 and 1 in pairs):
            time.sleep(0.1)
        origin = poses[0]["T_world_cam"][:3, 3]
        # frame 1: still where the IMU put it (stationary), not at the fix
        assert np.linalg.norm(poses[1]["T_world_cam"][:3, 3] - origin) < 1e-6
        assert np.allclose(pairs[0]["T_world_cam_t1"], poses[1]["T_world_cam"])
        # the pair (1, 2) starts from the fix and integrates from there
        assert np.allclose(pairs[1]["T_world_cam_t"][:3, 3] - origin, [5.0, 0.0, 0.0], atol=1e-6)
        assert np.allclose(poses[2]["T_world_cam"][:3, 3] - origin, [5.0, 0.0, 0.0], atol=1e-6)


def test_killed_service_is_restarted_by_atr_up(tmp_path):
    with _up_pose_integrator(tmp_path) as session:
        _kill_and_wait_restart(session, _wait_running(session, "pose_integrator"))
        poses = _collect(session, "atr/uav1/pose/camera")
        time.sleep(0.5)
        session.put("atr/uav1/imu", codec.pack(_good_imu(0)))
        deadline = time.monotonic() + 20
        while not poses and time.monotonic() < deadline:
            time.sleep(0.1)
        assert poses, "the restarted service did not answer"


def test_template_query_that_times_out_is_reported_and_the_matcher_goes_on(hub):
    # No template store on the bus: the matcher's template query times out for each cloud.
    with _service(hub, "atr_matcher", "--set", "pipeline.template_timeout_s=1") as (
        service,
        session,
    ):
        errors = _collect(session, "atr/uav1/atr_matcher/errors")
        time.sleep(0.5)
        for seq in range(2):
            cloud = example("PointCloud") | {"seq": seq, "stamp_ns": 5_000 + seq}
            session.put(
                "atr/uav1/sfm/cloud",
                codec.pack(cloud),
                congestion_control=zenoh.CongestionControl.BLOCK,
            )
        deadline = time.monotonic() + 60
        while len(errors) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert [e["input_stamp_ns"] for e in errors] == [5_000, 5_001]
        assert all(
            e["error_type"] == "BusError" and "atr/templates/" in e["reason"] for e in errors
        )
        assert service.poll() is None


def test_sfm_reports_a_bad_lens_and_reconstructs_the_next_pair(hub):
    with _service(hub, "sfm") as (service, session):
        errors = _collect(session, "atr/uav1/sfm/errors")
        clouds = _collect(session, "atr/uav1/sfm/cloud")
        time.sleep(0.5)
        texture = np.random.default_rng(5).integers(0, 255, (48, 64), dtype=np.uint8)
        lenses = {0: np.zeros(5), 1: np.array([0.1, 0.0, 0.0]), 2: np.zeros(0)}  # 1: 3 coefficients
        block = zenoh.CongestionControl.BLOCK
        for frame, lens in lenses.items():
            image = example("Image") | {
                "seq": frame,
                "stamp_ns": 1_000 + frame,
                "frame_seq": frame,
                "encoding": "mono8",
                "data": np.roll(texture, 2 * frame, axis=1),
                "distortion": lens,
            }
            session.put("atr/uav1/camera/image", codec.pack(image), congestion_control=block)
            if frame > 0:
                T_t1 = np.eye(4)
                T_t1[0, 3] = 0.5 * frame  # a sideways step per frame
                T_t = T_t1.copy()
                T_t[0, 3] -= 0.5
                pair = example("RelativePose") | {
                    "seq": frame - 1,
                    "stamp_ns": 1_000 + frame,
                    "stamp_ns_t": 1_000 + frame - 1,
                    "frame_seq_t": frame - 1,
                    "frame_seq_t1": frame,
                    "T_camt1_camt": np.linalg.inv(T_t1) @ T_t,
                    "T_world_cam_t": T_t,
                    "T_world_cam_t1": T_t1,
                }
                session.put("atr/uav1/pose/relative", codec.pack(pair), congestion_control=block)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not (errors and len(clouds) >= 2):
            time.sleep(0.1)
        assert len(errors) == 1 and "dist_coeffs has 3 coefficients" in errors[0]["reason"]
        assert errors[0]["input_stamp_ns"] == 1_001  # names frame 1
        # frame 0 is answered (no partner yet); frame 1's pair failed; frame 2's pair is reconstructed
        assert [c["frame_seqs"] for c in clouds] == [[0], [1, 2]]
        assert service.poll() is None  # still alive


def _batch(frame: int) -> dict:
    """Frame `frame`'s IMU batch of a stationary flight; frame 0 carries the initial state."""
    t = 1_000_000_000 + frame * 100_000_000 + np.arange(1, 21, dtype=np.int64) * 5_000_000
    batch = _good_imu(frame) | {"t_ns": t, "stamp_ns": int(t[-1])}
    if frame:
        del batch["init"]
    return batch


def test_a_killed_pose_integrator_restarts_from_its_checkpoint(tmp_path):
    """kill -9 mid-flight under `atr up`: the restarted process goes on with the flight's track."""
    with _up_pose_integrator(tmp_path, "--state-dir", f"'{tmp_path}'") as session:
        first = _wait_running(session, "pose_integrator")
        pairs = _collect_by(session, "atr/uav1/pose/relative", "frame_seq_t1")
        errors = _collect(session, "atr/uav1/pose_integrator/errors")
        time.sleep(0.5)

        def fly(frames: range) -> None:
            for frame in frames:
                session.put("atr/uav1/imu", codec.pack(_batch(frame)))
                deadline = time.monotonic() + 20
                while frame > 0 and frame not in pairs and time.monotonic() < deadline:
                    time.sleep(0.05)

        fly(range(4))
        _kill_and_wait_restart(session, first)
        time.sleep(0.5)
        fly(range(4, 7))
        assert sorted(pairs) == [1, 2, 3, 4, 5, 6], [e["reason"] for e in errors]
        assert not errors
        # the pair across the restart starts where the killed process left frame 3
        assert np.array_equal(pairs[4]["T_world_cam_t"], pairs[3]["T_world_cam_t1"])
    assert not list(tmp_path.glob("pose_integrator-*")), "a clean stop leaves no checkpoint"
