"""`atr regress` on the corpus in recordings/ (the CI gate), the determinism gate, and one setting changed
at a time caught by `atr diff` with its topic and first differing field. Real replays on a real bus."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
from _atr_cli import atr  # noqa: E402
from _small_camera import SMALL_CAMERA  # noqa: E402

CORPUS = REPO / "recordings"
BASELINE = CORPUS / "baselines"
TOLERANCES = CORPUS / "tolerances.yml"  # floating-point noise between CPUs, no more
FLIGHT = "s1-run3"

pytestmark = [pytest.mark.e2e, pytest.mark.slow]


def replay(source: Path, out: Path, *overrides: str) -> Path:
    # the corpus was recorded with the paper's sparse SfM (recordings/NAME.yml pins it too)
    done = atr(
        "run", str(source), "--out", str(out), *SMALL_CAMERA, "--preset", "paper", *overrides
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def test_the_corpus_replays_as_its_baselines(tmp_path):
    """Every change that alters what the pipeline publishes fails here until the baselines are updated
    on purpose (`atr regress recordings --baseline recordings/baselines --update`)."""
    junit = tmp_path / "regress.xml"
    done = atr(
        "regress",
        str(CORPUS),
        "--baseline",
        str(BASELINE),
        "--tolerances",
        str(TOLERANCES),
        "--junit",
        str(junit),
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "DIFFERS" not in done.stdout and junit.is_file()


def test_determinism_gate_a_run_and_a_replay_of_a_replay_are_identical(tmp_path):
    first = replay(CORPUS / f"{FLIGHT}.mcap", tmp_path / "first.mcap")
    again = replay(first, tmp_path / "again.mcap")  # the recording of a replay, replayed
    # the baseline, made on another CPU, within the corpus's floating-point noise; on one machine
    # a replay of a replay is byte-identical
    for a, b, tolerances in [
        (BASELINE / f"{FLIGHT}.mcap", first, ["--tolerances", str(TOLERANCES)]),
        (first, again, []),
    ]:
        done = atr("diff", str(a), str(b), *tolerances)
        assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.parametrize(
    ("setting", "topic"),
    [
        ("recognition.descriptor=fpfh", "atr/uav1/detections"),
        ("sfm.gftt_min_quality=0.01", "atr/uav1/sfm/cloud"),
        ("sfm.matcher=surf", "atr/uav1/sfm/cloud"),
    ],
)
def test_one_setting_changed_is_named_by_topic_and_first_field(setting, topic, tmp_path):
    changed = replay(CORPUS / f"{FLIGHT}.mcap", tmp_path / "changed.mcap", "--set", setting)
    # the corpus's tolerances accept floating-point noise, not a changed setting
    done = atr(
        "diff", str(BASELINE / f"{FLIGHT}.mcap"), str(changed), "--tolerances", str(TOLERANCES)
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"{topic}: DIFFERS" in done.stdout
    first = done.stdout.split(f"{topic}: DIFFERS", 1)[1].splitlines()[1]
    assert first.strip().startswith("first at stamp") and ": " in first.split(":", 1)[1]
