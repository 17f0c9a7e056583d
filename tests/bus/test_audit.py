"""`atr audit` on recordings built to hold one known fault each: lost messages, a restart, a frame
without an answer, a missing provenance record, a cut file; and its HTML page in a real browser."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import CompressionType
from mcap.writer import Writer as McapLibWriter

from bus import audit as auditing
from bus import codec

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _atr_cli import atr  # noqa: E402

PROVENANCE = {"package_version": "0.1.0", "config_sha256": "abc", "source_sha256": "def"}


def _detections(stamp_ns: int, seq: int, frame: int) -> bytes:
    T = np.eye(4)
    T[:3, 3] = [10.0 + frame, 20.0, 0.0]
    det = {
        "target": "t72",
        "descriptor": "shot",
        "T_world_target": T,
        "score": 0.8,
        "overlap": 0.6,
        "inliers": 17,
    }
    return codec.pack(
        {
            "stamp_ns": stamp_ns,
            "seq": seq,
            "version": 1,
            "frame_seqs": [frame - 1, frame],
            "detections": [det],
        }
    )


def _flight(
    path: Path,
    frames: int = 8,
    lose_detection: int | None = None,
    unanswered: int | None = None,
    error_frame: int | None = None,
    provenance: bool = True,
    restart_at: int | None = None,
) -> None:
    """Images and detections of a short flight, written with the reference writer."""
    with path.open("wb") as f:
        w = McapLibWriter(f, chunk_size=2000, compression=CompressionType.ZSTD)
        w.start(profile="", library="test")
        if provenance:
            w.add_metadata(auditing.PROVENANCE, PROVENANCE)
        schema = w.register_schema("Any", "jsonschema", b"{}")
        image = w.register_channel("atr/uav1/camera/image", "msgpack", schema)
        dets = w.register_channel("atr/uav1/detections", "msgpack", schema)
        errors = w.register_channel("atr/uav1/sfm/errors", "msgpack", schema)
        det_seq = 0
        for k in range(frames):
            stamp = 1_000_000_000 * (k + 1)
            img = codec.pack({"stamp_ns": stamp, "seq": k, "version": 1, "frame_seq": k})
            w.add_message(image, stamp, img, stamp, k)
            if k == error_frame:
                report = codec.pack(
                    {"stamp_ns": stamp, "seq": 0, "reason": "bad image", "input_stamp_ns": stamp}
                )
                w.add_message(errors, stamp + 5, report, stamp, 0)
                continue
            if k == restart_at:
                det_seq = 0
            if k != unanswered and k != lose_detection:
                w.add_message(dets, stamp + 10, _detections(stamp, det_seq, k), stamp, det_seq)
            if k != unanswered:
                det_seq += 1  # a lost message was sent: its number is used
        w.finish()


def test_a_complete_flight_audits_clean(tmp_path: Path) -> None:
    path = tmp_path / "f.mcap"
    _flight(path)
    report = auditing.audit(path)
    assert report.problems == [] and report.closed
    assert report.provenance == [PROVENANCE]
    assert len(report.decisions) == 8 and report.decisions[3].frame_seqs == [2, 3]
    assert report.decisions[3].position_m == (13.0, 20.0, 0.0)
    assert report.publishers["atr/uav1/detections"].count == 8


def test_lost_messages_are_counted_and_located(tmp_path: Path) -> None:
    path = tmp_path / "f.mcap"
    _flight(path, lose_detection=4)
    report = auditing.audit(path)
    assert report.publishers["atr/uav1/detections"].lost() == 1
    assert any("1 message(s) lost (sequence 3 -> 5)" in p for p in report.problems)
    assert report.unanswered_frames == [4]


def test_a_frame_without_answer_and_a_restart_are_told_apart(tmp_path: Path) -> None:
    path = tmp_path / "f.mcap"
    _flight(path, unanswered=2, restart_at=5, error_frame=6)
    report = auditing.audit(path)
    assert report.unanswered_frames == [2]  # frame 6 was answered by an error
    assert report.publishers["atr/uav1/detections"].restarts == [6_000_000_010]
    assert report.publishers["atr/uav1/detections"].lost() == 0
    assert [(s, r) for _, s, r in report.errors] == [("sfm", "bad image")]


def test_no_provenance_and_a_cut_file_are_problems(tmp_path: Path) -> None:
    path = tmp_path / "f.mcap"
    _flight(path, provenance=False)
    assert any("no provenance" in p for p in auditing.audit(path).problems)
    _flight(path)
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * 0.35)])
    report = auditing.audit(path)
    assert not report.closed
    assert any("not closed cleanly" in p for p in report.problems)
    assert 0 < len(report.decisions) < 8  # what is there is still read


def test_cli_exit_codes_and_json(tmp_path: Path) -> None:
    good, bad = tmp_path / "good.mcap", tmp_path / "bad.mcap"
    _flight(good)
    _flight(bad, lose_detection=3)
    ok = atr("audit", str(good), "--json", str(tmp_path / "a.json"))
    assert ok.returncode == 0 and "complete and consistent" in ok.stdout, ok.stderr
    assert (
        json.loads((tmp_path / "a.json").read_text())["publishers"]["atr/uav1/detections"]["count"]
        == 8
    )
    fail = atr("audit", str(bad))
    assert fail.returncode == 1 and "PROBLEM: atr/uav1/detections: 1 message(s) lost" in fail.stdout
    missing = atr("audit", str(tmp_path / "none.mcap"))
    assert missing.returncode == 2 and "does not exist" in missing.stderr
    for result in (ok, fail, missing):
        assert "Traceback" not in result.stderr


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(
    CHROMIUM is None, reason="Debian's chromium is not installed (./dev installs it)"
)
def test_the_html_page_renders_in_a_real_browser(tmp_path: Path) -> None:
    """The page is self-contained and shows the verdict, the problems, the decisions and the figure:
    Chromium renders it headless and dumps the DOM it built."""
    path = tmp_path / "f.mcap"
    _flight(path, lose_detection=4)
    page = tmp_path / "audit.html"
    page.write_text(auditing.render_html(auditing.audit(path)))
    assert "http://" not in page.read_text() and "https://" not in page.read_text()
    script = (
        "<script>window.onload=()=>{const i=document.getElementById('figure');"
        "document.title=[i.complete,i.naturalWidth,document.querySelectorAll('#decisions tr').length].join(',')}"
        "</script>"
    )
    probe = tmp_path / "probe.html"
    probe.write_text(page.read_text().replace("</body>", script + "</body>"))
    result = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--dump-dom", probe.as_uri()],
        capture_output=True,
        text=True,
        timeout=120,
    )
    dom = result.stdout
    assert "2 problem(s)" in dom and "sequence 3 -&gt; 5" in dom, result.stderr[-2000:]
    title = dom.split("<title>")[1].split("</title>")[0]
    complete, width, rows = title.split(",")
    assert complete == "true" and int(width) > 500  # the inline figure decoded
    assert int(rows) == 1 + 7  # header and the seven recorded detections
    shot = tmp_path / "shot.png"
    subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            f"--screenshot={shot}",
            "--window-size=1300,1400",
            page.as_uri(),
        ],
        capture_output=True,
        timeout=120,
    )
    assert shot.stat().st_size > 20_000  # a real picture, not a blank page
