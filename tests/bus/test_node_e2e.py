"""The service runtime over a real Zenoh bus: other processes, real sessions on loopback, multicast off."""

from __future__ import annotations

import subprocess
import sys
import time
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


def _service(name: str, hub: str, *args: str) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "cli.main", "service", name, *args],
        env=bus_env(hub),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )


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
    service = _service("pose_integrator", hub)
    session = open_session(peer_config(hub))
    try:
        _wait_running(session, "pose_integrator")
        errors, poses = [], []
        session.declare_subscriber(
            "atr/uav1/pose_integrator/errors",
            lambda s: errors.append(codec.unpack(s.payload.to_bytes())),
        )
        session.declare_subscriber(
            "atr/uav1/pose/camera", lambda s: poses.append(codec.unpack(s.payload.to_bytes()))
        )
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
    finally:
        session.close()
        stop_process(service)


def test_pose_integrator_applies_a_later_init_as_a_navigation_fix(hub):
    """sim.nav_fix_every_frame: a batch's `init` after the first is a fix at its frame; that frame's pose
    is still integrated (the pair ending there used it) and the next pair starts from the fix."""
    service = _service("pose_integrator", hub)
    session = open_session(peer_config(hub))
    try:
        _wait_running(session, "pose_integrator")
        poses, pairs = {}, {}
        session.declare_subscriber(
            "atr/uav1/pose/camera",
            lambda s: poses.update({(m := codec.unpack(s.payload.to_bytes()))["frame_seq"]: m}),
        )
        session.declare_subscriber(
            "atr/uav1/pose/relative",
            lambda s: pairs.update({(m := codec.unpack(s.payload.to_bytes()))["frame_seq_t"]: m}),
        )
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
    finally:
        session.close()
        stop_process(service)


def test_killed_service_is_restarted_by_atr_up(tmp_path):
    port = free_port()
    layout = tmp_path / "mini.yml"
    layout.write_text(
        f"name: mini\nvariables: {{uav: uav1, hub: 'tcp/127.0.0.1:{port}'}}\n"
        "zenoh: compose/zenoh/local.json5\n"
        "processes:\n  - {name: router, service: router, role: hub, args: [--listen, '${hub}']}\n"
        "  - {name: pose_integrator, service: pose_integrator}\n"
    )
    env = bus_env(f"tcp/127.0.0.1:{port}")
    up = subprocess.Popen(
        [sys.executable, "-m", "cli.main", "up", str(layout)],
        env=env,
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        wait_for_port(port, 30)
        session = open_session(peer_config(f"tcp/127.0.0.1:{port}"))
        try:
            first = _wait_running(session, "pose_integrator")
            subprocess.run(["kill", "-9", str(first["pid"])], check=True)
            deadline = time.monotonic() + 60
            second = first
            while second["pid"] == first["pid"] and time.monotonic() < deadline:
                second = _wait_running(session, "pose_integrator", 60)
            assert second["pid"] != first["pid"]
            poses = []
            session.declare_subscriber("atr/uav1/pose/camera", lambda s: poses.append(1))
            time.sleep(0.5)
            session.put("atr/uav1/imu", codec.pack(_good_imu(0)))
            deadline = time.monotonic() + 20
            while not poses and time.monotonic() < deadline:
                time.sleep(0.1)
            assert poses, "the restarted service did not answer"
        finally:
            session.close()
    finally:
        assert stop_process(up, 30) == 0


def test_template_query_that_times_out_is_reported_and_the_matcher_goes_on(hub):
    # No template store on the bus: the matcher's template query times out for each cloud.
    service = _service("atr_matcher", hub, "--set", "pipeline.template_timeout_s=1")
    session = open_session(peer_config(hub))
    try:
        _wait_running(session, "atr_matcher")
        errors = []
        session.declare_subscriber(
            "atr/uav1/atr_matcher/errors",
            lambda s: errors.append(codec.unpack(s.payload.to_bytes())),
        )
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
    finally:
        session.close()
        stop_process(service)


def test_sfm_reports_a_bad_lens_and_reconstructs_the_next_pair(hub):
    service = _service("sfm", hub)
    session = open_session(peer_config(hub))
    try:
        _wait_running(session, "sfm")
        errors, clouds = [], []
        session.declare_subscriber(
            "atr/uav1/sfm/errors", lambda s: errors.append(codec.unpack(s.payload.to_bytes()))
        )
        session.declare_subscriber(
            "atr/uav1/sfm/cloud", lambda s: clouds.append(codec.unpack(s.payload.to_bytes()))
        )
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
    finally:
        session.close()
        stop_process(service)


def _batch(frame: int) -> dict:
    """Frame `frame`'s IMU batch of a stationary flight; frame 0 carries the initial state."""
    t = 1_000_000_000 + frame * 100_000_000 + np.arange(1, 21, dtype=np.int64) * 5_000_000
    batch = _good_imu(frame) | {"t_ns": t, "stamp_ns": int(t[-1])}
    if frame:
        del batch["init"]
    return batch


def test_a_killed_pose_integrator_restarts_from_its_checkpoint(tmp_path):
    """kill -9 mid-flight under `atr up`: the restarted process goes on with the flight's track."""
    port = free_port()
    layout = tmp_path / "mini.yml"
    layout.write_text(
        f"name: mini\nvariables: {{uav: uav1, hub: 'tcp/127.0.0.1:{port}'}}\n"
        "zenoh: compose/zenoh/local.json5\n"
        "processes:\n  - {name: router, service: router, role: hub, args: [--listen, '${hub}']}\n"
        f"  - {{name: pose_integrator, service: pose_integrator, args: [--state-dir, '{tmp_path}']}}\n"
    )
    up = subprocess.Popen(
        [sys.executable, "-m", "cli.main", "up", str(layout)],
        env=bus_env(f"tcp/127.0.0.1:{port}"),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        wait_for_port(port, 30)
        session = open_session(peer_config(f"tcp/127.0.0.1:{port}"))
        try:
            first = _wait_running(session, "pose_integrator")
            pairs, errors = {}, []
            session.declare_subscriber(
                "atr/uav1/pose/relative",
                lambda s: pairs.update(
                    {(m := codec.unpack(s.payload.to_bytes()))["frame_seq_t1"]: m}
                ),
            )
            session.declare_subscriber(
                "atr/uav1/pose_integrator/errors",
                lambda s: errors.append(codec.unpack(s.payload.to_bytes())["reason"]),
            )
            time.sleep(0.5)

            def fly(frames: range) -> None:
                for frame in frames:
                    session.put("atr/uav1/imu", codec.pack(_batch(frame)))
                    deadline = time.monotonic() + 20
                    while frame > 0 and frame not in pairs and time.monotonic() < deadline:
                        time.sleep(0.05)

            fly(range(4))
            subprocess.run(["kill", "-9", str(first["pid"])], check=True)
            second = first
            deadline = time.monotonic() + 60
            while second["pid"] == first["pid"] and time.monotonic() < deadline:
                second = _wait_running(session, "pose_integrator", 60)
            time.sleep(0.5)
            fly(range(4, 7))
            assert sorted(pairs) == [1, 2, 3, 4, 5, 6], errors
            assert not errors
            # the pair across the restart starts where the killed process left frame 3
            assert np.array_equal(pairs[4]["T_world_cam_t"], pairs[3]["T_world_cam_t1"])
        finally:
            session.close()
    finally:
        assert stop_process(up, 30) == 0
    assert not list(tmp_path.glob("pose_integrator-*")), "a clean stop leaves no checkpoint"
