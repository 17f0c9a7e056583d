"""`atr certs` refuses a bad ground address or output folder, naming it, before it writes anything."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _atr_cli import atr  # noqa: E402


@pytest.mark.parametrize(
    ("ground", "expected"),
    [
        ("not-an-address!!", "neither an IP address"),
        ("ground:7447", "the port goes in --port"),
        ("bad_name.example.org", "host name"),
    ],
)
def test_a_bad_ground_address_is_refused_naming_it(
    tmp_path: Path, ground: str, expected: str
) -> None:
    done = atr("certs", "--out", "deploy", "--ground", ground, cwd=tmp_path)
    assert done.returncode == 1, done.stdout
    assert "Traceback" not in done.stderr
    assert repr(ground) in done.stderr and expected in done.stderr, done.stderr
    assert not (tmp_path / "deploy").exists()


def test_an_out_that_is_a_file_is_refused(tmp_path: Path) -> None:
    (tmp_path / "deploy").write_text("")
    done = atr("certs", "--out", "deploy", "--ground", "10.0.0.1", cwd=tmp_path)
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert "--out deploy is a file" in done.stderr, done.stderr


def test_the_air_recorder_gets_a_signing_key_once(tmp_path: Path) -> None:
    """`atr certs` makes the air recorder's Ed25519 pair beside the certificates; a second run keeps
    it, since the ground has pinned the public key."""
    first = atr("certs", "--out", "deploy", "--ground", "127.0.0.1", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    public = tmp_path / "deploy" / "air-uav1-recorder.pub"
    private = tmp_path / "deploy" / "air-uav1-recorder.key"
    assert public.is_file() and private.is_file()
    assert private.stat().st_mode & 0o077 == 0  # the owner's only
    pinned = public.read_bytes()
    again = atr("certs", "--out", "deploy", "--ground", "127.0.0.1", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert public.read_bytes() == pinned
