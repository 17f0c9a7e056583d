"""`atr diff` as a user runs it: exit codes 0/1/2, the summary names topic and field, JUnit and JSON lines."""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from cli.main import main

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "bus"))
sys.path.insert(0, str(REPO / "tests"))
from _atr_cli import atr  # noqa: E402
from test_diff import CLOUD, DETECTIONS, STAMPS, STATUS, flight, write  # noqa: E402


@pytest.fixture
def pair(tmp_path) -> tuple[Path, Path, Path]:
    base = write(tmp_path / "base.mcap", flight())
    same = write(tmp_path / "same.mcap", flight(clock=3))
    changed = write(tmp_path / "changed.mcap", flight(point=1e-3))
    return base, same, changed


def test_same_exits_0_and_different_exits_1_naming_topic_and_field(pair, capsys):
    base, same, changed = pair
    assert main(["diff", str(base), str(same)]) == 0
    assert "SAME" in capsys.readouterr().out
    assert main(["diff", str(base), str(changed)]) == 1
    out = capsys.readouterr().out
    assert f"{CLOUD}: DIFFERS" in out and "points_m[3,1]" in out and "DIFFERENT: 1 of" in out


def test_junit_has_a_failure_exactly_where_it_differs_and_jsonl_a_line_per_frame(pair, tmp_path):
    base, _, changed = pair
    junit, jsonl = tmp_path / "diff.xml", tmp_path / "frames.jsonl"
    assert (
        main(["diff", str(base), str(changed), "--junit", str(junit), "--jsonl", str(jsonl)]) == 1
    )
    cases = {c.get("name"): c for c in ET.parse(junit).getroot().iter("testcase")}
    assert cases[CLOUD].find("failure") is not None
    assert "points_m[3,1]" in cases[CLOUD].find("failure").get("message")
    assert cases[DETECTIONS].find("failure") is None
    assert cases[STATUS].find("skipped") is not None
    frames = [json.loads(line) for line in jsonl.read_text().splitlines()]
    assert [f["stamp_ns"] for f in frames] == STAMPS
    assert [f["result"] for f in frames] == ["identical", "differs", "identical"]
    assert frames[1]["topics"][CLOUD]["first_difference"]["path"] == "points_m[3,1]"


def test_a_tolerance_file_hides_the_change(pair, tmp_path):
    base, _, changed = pair
    rules = tmp_path / "tolerances.yml"
    rules.write_text('rules:\n  - {topic: "atr/*/sfm/cloud", field: points_m, abs: 0.01}\n')
    assert main(["diff", str(base), str(changed), "--tolerances", str(rules)]) == 0


def test_errors_exit_2_with_a_message_and_no_traceback(pair, tmp_path, capsys):
    base, _, _ = pair
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 50)
    bad_rules = tmp_path / "bad.yml"
    bad_rules.write_text("rules:\n  - {topic: x, field: y, abs: -2}\n")
    for argv, said in [
        (["diff", str(base), str(garbage)], "garbage.mcap"),
        (["diff", str(base), str(tmp_path / "missing.mcap")], "does not exist"),
        (["diff", str(base), str(base), "--tolerances", str(bad_rules)], "'abs' is -2"),
    ]:
        assert main(argv) == 2
        assert said in capsys.readouterr().err
    done = atr("diff", str(base), "--bogus")
    assert done.returncode == 2 and "Traceback" not in done.stderr and "usage" in done.stderr
