"""Smoke evaluation for CI: `atr eval` on one scene writes the contract JSON, resumes from its result files,
and `atr report` turns the result into a report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _small_flight import SMALL_CAMERA as SMALL  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
CONTRACT = {
    "scenario",
    "run",
    "pipeline",
    "descriptor",
    "noise",
    "tp",
    "fp",
    "fn",
    "f1",
    "t_error_median_m",
    "time_per_scene_ms",
    "scenes",
    "track_tp",
    "track_fp",
    "track_fn",
    "track_f1",
    "false_tracks",
    "scenes_to_confirm",
    "track_held_while_hidden",
    "track_t_error_median_m",
}


def atr(*args: str) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(
        [sys.executable, "-m", "cli.main", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return result


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    root = tmp_path_factory.mktemp("eval")
    args = [
        "eval",
        "--scenario",
        "1",
        "--run",
        "3",
        "--frames",
        "2",
        "--pipeline",
        "gftt-sfm",
        "--descriptor",
        "shot",
        *SMALL,
        "--results",
        str(root / "results"),
        "--json",
        str(root / "out.json"),
    ]
    first = atr(*args)
    second = atr(*args)
    return root, args, first, second


def test_json_is_the_contract(evaluated):
    root, _, _, _ = evaluated
    data = json.loads((root / "out.json").read_text())
    assert list(data) == ["results"] and len(data["results"]) == 1
    row = data["results"][0]
    assert set(row) == CONTRACT
    assert (row["scenario"], row["run"], row["pipeline"], row["descriptor"], row["noise"]) == (
        1,
        3,
        "gftt-sfm",
        "shot",
        "none",
    )
    assert row["scenes"] == 1 and row["tp"] + row["fp"] + row["fn"] <= 1
    if row["tp"] + row["fp"] + row["fn"]:
        assert row["f1"] == pytest.approx(2 * row["tp"] / (2 * row["tp"] + row["fp"] + row["fn"]))


def test_results_folder_and_resume(evaluated):
    root, _, first, second = evaluated
    latest = root / "results" / "latest"
    assert latest.is_symlink()
    config = json.loads((latest / "config.json").read_text())
    assert config["atr"]["sim"]["width_px"] == 640 and config["code_version"]
    # the command that made it, without the files it wrote to (no machine path in a result)
    assert config["command"][:4] == ["atr", "eval", "--scenario", "1"]
    assert "--results" not in config["command"] and "--json" not in config["command"]
    assert str(root) not in " ".join(config["command"])
    assert "0 current results reused" in first.stderr
    assert "1 current results reused" in second.stderr
    assert (
        json.loads((latest / "results.json").read_text())["results"]
        == json.loads((root / "out.json").read_text())["results"]
    )


def test_report_from_the_result(evaluated, tmp_path):
    root, _, _, _ = evaluated
    atr("report", "--results", str(root / "results" / "latest"), "--out", str(tmp_path))
    readme, details = ((tmp_path / page).read_text() for page in ("README.md", "details.md"))
    assert "## The paper's claims, tested" in readme and "gftt-sfm/shot" in readme
    assert "[details.md](details.md)" in readme
    assert "Fig. 4" in details and "gftt-sfm/shot" in details and "Table V" in details
    assert (tmp_path / "data" / "results.json").exists()
