"""The split deployment's security on loopback: mutual TLS, access control, images kept on the air.

A ground router, a ground client, the air router and an air client run with the certificates and configs of
`make_deployment` (what `atr certs` writes), each its own Zenoh session in this process.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import json5
import pytest
import zenoh

from bus.certs import Deployment, make_deployment

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from conftest import free_port  # noqa: E402

pytestmark = [pytest.mark.e2e]

UAV = "uav1"


def _config(deploy: Deployment, name: str) -> dict[str, Any]:
    return json5.loads(deploy.zenoh(name).read_text())


def _open(config: dict[str, Any]) -> zenoh.Session:
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


class Inbox:
    """What a subscriber received: (key, payload)."""

    def __init__(self, session: zenoh.Session, key_expr: str) -> None:
        self.items: list[tuple[str, bytes]] = []
        self._lock = threading.Lock()
        self._sub = session.declare_subscriber(key_expr, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        with self._lock:
            self.items.append((str(sample.key_expr), sample.payload.to_bytes()))

    def keys(self) -> set[str]:
        with self._lock:
            return {k for k, _ in self.items}


@pytest.fixture(scope="module")
def deployment(tmp_path_factory: pytest.TempPathFactory) -> Deployment:
    port, air_port = free_port(), free_port()
    return make_deployment(
        tmp_path_factory.mktemp("deploy"), ground="127.0.0.1", port=port, air_port=air_port
    )


@pytest.fixture(scope="module")
def bus(deployment: Deployment) -> Iterator[dict[str, Any]]:
    sessions: list[zenoh.Session] = []
    try:
        sessions.append(_open(_config(deployment, "split-ground-router")))
        ground = _open(_config(deployment, "split-ground"))
        sessions.append(ground)
        sessions.append(_open(_config(deployment, "split-air-router")))
        air = _open(_config(deployment, "split-air"))
        sessions.append(air)
        ground_inbox = Inbox(ground, "**")
        queryable = ground.declare_queryable(
            "atr/templates/**", lambda q: q.reply(str(q.key_expr), b"template")
        )
        deadline = time.monotonic() + 20
        while not air.info.routers_zid() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)  # the routers exchange their declarations
        yield {"ground": ground, "air": air, "inbox": ground_inbox, "queryable": queryable}
    finally:
        for session in reversed(sessions):
            session.close()


def test_certificates_chain_to_the_deployment_ca(deployment: Deployment) -> None:
    for name in ("ground-router", "ground", f"air-{UAV}"):
        result = subprocess.run(
            [
                "openssl",
                "verify",
                "-CAfile",
                str(deployment.cert("ca")),
                str(deployment.cert(name)),
            ],
            capture_output=True,
            text=True,
        )
        assert result.returncode == 0, result.stderr
        subject = subprocess.run(
            ["openssl", "x509", "-in", str(deployment.cert(name)), "-noout", "-subject"],
            capture_output=True,
            text=True,
        ).stdout
        assert subject.strip().endswith(f"CN = {name}"), subject
        assert deployment.key(name).stat().st_mode & 0o077 == 0, f"{name}.key is readable by others"
    text = subprocess.run(
        [
            "openssl",
            "x509",
            "-in",
            str(deployment.cert("ground-router")),
            "-noout",
            "-ext",
            "subjectAltName",
        ],
        capture_output=True,
        text=True,
    ).stdout
    assert "IP Address:127.0.0.1" in text


def test_client_without_credentials_cannot_connect(
    deployment: Deployment, bus: dict[str, Any], tmp_path: Path
) -> None:
    port = deployment.port
    no_cert = _config(deployment, "split-ground")
    tls = no_cert["transport"]["link"]["tls"]
    del tls["connect_certificate"], tls["connect_private_key"]
    plain = {
        "mode": "client",
        "connect": {"endpoints": [f"tcp/127.0.0.1:{port}"], "timeout_ms": 2000},
        "scouting": {"multicast": {"enabled": False}},
    }
    # a certificate of another CA, with the right common name
    other = make_deployment(tmp_path / "other", ground="127.0.0.1", port=port)
    forged = _config(other, "split-ground")
    for config in (no_cert, plain, forged):
        config["connect"]["timeout_ms"] = 2000
        before = len(bus["inbox"].items)
        with pytest.raises(zenoh.ZError):
            session = _open(config)  # neither subscribe nor publish: there is no session at all
            session.put(f"atr/{UAV}/detections", b"intruder")
            session.close()
        time.sleep(0.3)
        assert len(bus["inbox"].items) == before


def test_air_publishes_only_its_own_sensor_keys(bus: dict[str, Any]) -> None:
    air, ground, inbox = bus["air"], bus["ground"], bus["inbox"]
    allowed = [
        f"atr/{UAV}/imu",
        f"atr/{UAV}/sfm/cloud",
        f"atr/{UAV}/pose/relative",
        f"sim/{UAV}/truth",
        f"atr/{UAV}/sfm/status",
    ]
    denied = [
        f"atr/{UAV}/detections",
        "atr/uav2/imu",
        f"atr/{UAV}/atr_matcher/status",
        "atr/templates/t72/shot",
        "elsewhere/key",
    ]
    for key in allowed + denied:
        air.put(key, b"from-air")
    ground.put(f"atr/{UAV}/detections", b"from-ground")
    deadline = time.monotonic() + 5
    while not set(allowed) <= inbox.keys() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)
    got = {(k, p) for k, p in inbox.items}
    for key in allowed:
        assert (key, b"from-air") in got, f"{key} from the air did not reach the ground"
    for key in denied:
        assert (key, b"from-air") not in got, f"the air could publish {key}"
    assert (f"atr/{UAV}/detections", b"from-ground") in got


def test_camera_images_stay_on_the_air(bus: dict[str, Any]) -> None:
    air, inbox = bus["air"], bus["inbox"]
    local = Inbox(air, f"atr/{UAV}/camera/image")
    time.sleep(0.3)
    air.put(f"atr/{UAV}/camera/image", b"pixels")
    air.put(f"atr/{UAV}/imu", b"after-image")
    deadline = time.monotonic() + 5
    while (f"atr/{UAV}/imu", b"after-image") not in inbox.items and time.monotonic() < deadline:
        time.sleep(0.1)
    assert local.keys() == {f"atr/{UAV}/camera/image"}, (
        "the air's own subscriber did not get the image"
    )
    assert f"atr/{UAV}/camera/image" not in inbox.keys(), "a camera image crossed to the ground"


def test_air_may_query_templates_and_receive_detections(bus: dict[str, Any]) -> None:
    air, ground = bus["air"], bus["ground"]
    replies = [
        r.ok.payload.to_bytes() for r in air.get("atr/templates/t72/shot", timeout=5) if r.ok
    ]
    assert replies == [b"template"]
    inbox = Inbox(air, f"atr/{UAV}/detections")
    time.sleep(0.5)
    ground.put(f"atr/{UAV}/detections", b"answer")
    deadline = time.monotonic() + 5
    while not inbox.items and time.monotonic() < deadline:
        time.sleep(0.1)
    assert inbox.items == [(f"atr/{UAV}/detections", b"answer")]
