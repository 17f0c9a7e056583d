"""`atr report`: Fig. 7 (recognised scenes of a recorded flight, drawn in the true world frame), the
table of which arms really differ, the verdict per claim of the paper, and the pages it writes."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from atr.evaluation.aggregate import (
    PAPER_TABLE_V_STORAGE_KB,
    arm_label,
    median_interval,
    paper_template_kb,
    pool,
)
from bus import keys
from cli.report import (
    COUNTED_DIFFERENTLY,
    DOES_NOT,
    EXAMPLE_RADIUS_M,
    HOLDS,
    NOT_SHOWN,
    REPO,
    Figures,
    _differences_section,
    _examples_section,
    _false_positives_section,
    _navigation_section,
    _paper_rows,
    _scene_outcomes,
    _targets_section,
    _time_vs_reference,
    _tracks_section,
    _verdict_section,
    bound_verdict,
    example_scenes,
    latest_rows,
    level_verdict,
    order_verdict,
    run,
    tie_verdict,
    verdicts,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_flight_report import (  # noqa: E402
    STAMP_NS,
    T_CAM_EST,
    T_CAM_TRUE,
    TARGET_M,
    messages,
    seen_through_the_estimated_pose,
    write_recording,
)


def sfm_cloud(points_true_m: np.ndarray) -> dict:
    """The PointCloud the sfm service publishes: positions placed with the estimated camera pose."""
    est_from_true = T_CAM_EST @ np.linalg.inv(T_CAM_TRUE)
    points = points_true_m @ est_from_true[:3, :3].T + est_from_true[:3, 3]
    return {
        "stamp_ns": STAMP_NS,
        "seq": 1,
        "version": 1,
        "source": "sfm-gftt",
        "frame_seqs": [0, 1],
        "points_m": points.astype(np.float32),
        "sigma_m": np.full(len(points), 0.1, np.float32),
        "viewpoint_m": T_CAM_EST[:3, 3],
    }


def flight(path: Path, T_found: np.ndarray) -> np.ndarray:
    """A one-scene recording: a hull-sized box of points at the target and ground 20 m away."""
    rng = np.random.default_rng(3)
    hull = TARGET_M + rng.uniform([-3.0, -1.5, 0.0], [3.0, 1.5, 2.2], size=(300, 3))
    far = TARGET_M + np.array([20.0, 0.0, 0.0]) + rng.uniform(-1.0, 1.0, size=(50, 3))
    truth, detections, camera_pose = messages("sfm-gftt", T_found)
    write_recording(
        path,
        [
            (keys.truth("uav1"), truth),
            (keys.camera_pose("uav1"), camera_pose),
            (keys.sfm_cloud("uav1"), sfm_cloud(np.vstack([hull, far]))),
            (keys.detections("uav1"), detections),
        ],
    )
    return hull


def test_a_recognised_scene_is_drawn_in_the_true_frame(tmp_path: Path):
    path = tmp_path / "flight.mcap"
    hull = flight(path, seen_through_the_estimated_pose())  # a TP relative to the sensor
    [scene] = example_scenes(path)
    # the cloud is brought back from the drifted frame; only the points around the target are kept
    assert len(scene.cloud_m) == len(hull)
    assert np.allclose(np.sort(scene.cloud_m, axis=0), np.sort(hull, axis=0), atol=1e-4)
    assert np.max(np.linalg.norm(scene.cloud_m[:, :2] - TARGET_M[:2], axis=1)) < EXAMPLE_RADIUS_M
    # the model stands where the detection put it, which is the true target position here
    assert np.linalg.norm(np.median(scene.model_m[:, :2], axis=0) - TARGET_M[:2]) < 1.0
    assert np.allclose(scene.target_m, TARGET_M) and np.allclose(scene.camera_m, T_CAM_TRUE[:3, 3])
    # seen from the side: heights kept, the horizontal offset taken across the line of sight (here y)
    across, height = scene.side_view()[0].T
    assert np.array_equal(height, scene.cloud_m[:, 2])
    assert np.allclose(np.abs(across), np.abs(scene.cloud_m[:, 1] - TARGET_M[1]), atol=1e-6)
    section = "\n".join(_examples_section(Figures(tmp_path), path))
    assert "fig7_examples.png" in section and (tmp_path / "fig7_examples.png").stat().st_size > 0
    # drawn again from the same recording, the figure is the same file (no churn in docs/)
    first = (tmp_path / "fig7_examples.png").read_bytes()
    _examples_section(Figures(tmp_path), path)
    assert (tmp_path / "fig7_examples.png").read_bytes() == first


def test_a_flight_without_a_true_positive_has_nothing_to_draw(tmp_path: Path):
    path = tmp_path / "flight.mcap"
    T_off = seen_through_the_estimated_pose()
    T_off[:3, 3] += [5.0, 0.0, 0.0]  # 5 m off the target: an FP
    flight(path, T_off)
    assert example_scenes(path) == []
    assert "holds no recognised scene" in "\n".join(_examples_section(Figures(tmp_path), path))


def _run_row(pipeline: str, descriptor: str, run: int, outcomes: list[str]) -> dict:
    return {
        "scenario": 1,
        "run": run,
        "pipeline": pipeline,
        "descriptor": descriptor,
        "scenes": len(outcomes),
        "outcomes": outcomes,
        **{k: outcomes.count(k) for k in ("tp", "fp", "fn", "tn")},
    }


def test_the_report_tells_a_real_difference_from_noise():
    rng = np.random.default_rng(11)
    best = [[str(o) for o in rng.choice(["tp", "fn"], size=60, p=[0.9, 0.1])] for _ in range(2)]
    # one scene more missed: noise; every other true positive missed: a real difference
    first_tp = best[0].index("tp")
    close = [best[0][:first_tp] + ["fn"] + best[0][first_tp + 1 :], best[1]]
    worse = [[o if i % 2 else "fn" for i, o in enumerate(run)] for run in best]
    rows = [
        _run_row(p, d, run + 1, outcomes[run])
        for p, d, outcomes in (
            ("gftt-sfm", "rops", best),
            ("gftt-sfm", "shot", close),
            ("lidar", "shot", worse),
        )
        for run in range(2)
    ]
    rows.append(_run_row("gftt-sfm", "usc", 1, best[0]))  # one run only: not the same scenes
    rows.append({**_run_row("gftt-sfm", "usc", 2, best[1]), "outcomes": None})
    overall = pool(rows, arm_label)
    outcomes = _scene_outcomes(rows)
    assert set(outcomes) == {"gftt-sfm/rops", "gftt-sfm/shot", "lidar/shot"}
    section = "\n".join(_differences_section(overall, outcomes))
    assert "against gftt-sfm/rops" in section
    table = {
        line.split(" | ")[0][2:]: line.split(" | ")
        for line in section.splitlines()
        if line.startswith("| gftt") or line.startswith("| lidar")
    }
    assert set(table) == {"gftt-sfm/shot", "lidar/shot"}
    assert table["gftt-sfm/shot"][-1].startswith("no")
    assert table["lidar/shot"][-1].startswith("yes")


def test_false_positives_are_pooled_per_arm_by_what_they_sit_on():
    rows = [
        {
            **_run_row("sgm-sfm", "shot", 1, ["fp"] * 3),
            "false_positives_on": {"ifv": 2, "elsewhere": 1},
        },
        {**_run_row("sgm-sfm", "shot", 2, ["fp"] * 2), "false_positives_on": {"ifv": 1, "car": 1}},
        {**_run_row("lidar", "shot", 1, ["tp"]), "false_positives_on": {}},
    ]
    section = "\n".join(_false_positives_section(rows))
    lines = [line for line in section.splitlines() if line.startswith("| ")]
    header = lines[0].strip("| ").split(" | ")
    assert header == ["pipeline / descriptor", "FP", "car", "ifv", "elsewhere", "on a vehicle"]
    table = {line.split(" | ")[0][2:]: line.strip("| ").split(" | ")[1:] for line in lines[1:]}
    assert table["sgm-sfm/shot"] == ["5", "1", "3", "1", "80.0%"]
    assert table["lidar/shot"] == ["0", "0", "0", "0", "–"]
    # a result written before the field existed gets no section rather than a wrong one
    del rows[0]["false_positives_on"]
    assert _false_positives_section(rows) == []


def test_time_over_the_reference_is_pooled_by_scenes_and_skips_rows_without_one():
    rows = [
        {"time_per_scene_ms": 600.0, "reference_ms": 10.0, "scenes": 30},  # 60 x
        {"time_per_scene_ms": 300.0, "reference_ms": 20.0, "scenes": 10},  # 15 x
        {
            "time_per_scene_ms": 900.0,
            "reference_ms": None,
            "scenes": 50,
        },  # computed before it was kept
    ]
    assert _time_vs_reference(rows) == (60.0 * 30 + 15.0 * 10) / 40
    assert _time_vs_reference(rows[2:]) is None


def test_tracks_are_pooled_per_arm_beside_the_per_scene_f1_and_run_by_run():
    def row(run: int, outcomes: list[str], track: tuple[int, int, int], false: int, confirm: float):
        return {
            **_run_row("sgm-sfm", "shot", run, outcomes),
            "t_errors_m": [0.2] * outcomes.count("tp"),
            **dict(zip(("track_tp", "track_fp", "track_fn"), track, strict=True)),
            "false_tracks": false,
            "scenes_to_confirm": confirm,
            "track_t_error_median_m": 0.1 * run,
        }

    rows = [
        row(1, ["tp"] * 9 + ["fp"], (8, 0, 2), 0, 2.0),
        row(2, ["tp"] * 10, (9, 0, 1), 1, float("nan")),  # a run that never confirmed
        {**_run_row("lidar", "shot", 1, ["tp"])},  # a result without track fields: no row
    ]
    text = "\n".join(_tracks_section(rows))
    lines = [line for line in text.splitlines() if line.startswith("| sgm")]
    overall, per_run = (line.strip("| ").split(" | ") for line in lines)
    # counts are summed before F1: scenes 19/1/0, tracks 17/0/3 -> 2*17 / (2*17 + 3)
    assert overall[1] == "97.4%" and overall[2] == "91.9% (17/0/3)"
    assert overall[3] == "5.0"  # one false track in 20 scenes
    assert overall[4] == "2"  # the run that never confirmed has no figure to pool
    assert overall[5:] == ["0.20", "0.15"]
    assert per_run == ["sgm-sfm/shot", "94.7% / 88.9%", "100.0% / 94.7%"]
    assert "| lidar" not in text
    assert _tracks_section(rows[2:]) == []


def test_a_result_of_several_targets_gets_a_per_target_table_and_paper_sections_read_the_t72():
    def row(target: str, run: int, outcomes: list[str]) -> dict:
        tp = outcomes.count("tp")
        return {
            **_run_row("sgm-sfm", "shot", run, outcomes),
            "target": target,
            "noise": "none",
            "range_m": 50.0,
            "obliquity_deg": 15.0 * run,
            "t_errors_m": [0.1] * tp,
            "false_positives_on": {"t72": outcomes.count("fp")},
            "template_storage_kb": {"t72": 1900.0, "m109": 2100.4}[target],
        }

    rows = [row("t72", 1, ["tp"] * 4), row("m109", 1, ["tp", "fp"]), row("m109", 2, ["fn"] * 2)]
    assert [r["target"] for r in _paper_rows(rows)] == ["t72"]
    assert _paper_rows(rows[1:]) == rows[1:]  # one target, whichever: all of its rows
    text = "\n".join(_targets_section(rows))
    lines = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    table = {line.strip("| ").split(" | ")[0]: line.strip("| ").split(" | ")[1:] for line in lines}
    assert "m109" in table and "t72 (tuned on)" in table
    # the held-out pool is the M109's alone: 1/1/2 -> F1 2/(2+1+2); one scene of 4 has its FP on a vehicle
    assert table["held out, all"][-4].startswith("0.40 (1/1/2)")
    assert table["held out, all"][-3] == "25.0%"
    assert table["m109"][-1] == "2100" and table["t72 (tuned on)"][-1] == "1900"  # its own template
    assert _targets_section(rows[:1]) == []  # a single target: no section


# ------------------------------------------------------------------------------------------- verdicts

PAPER_RUNS = [
    (1, 1, 30.0),
    (1, 2, 0.0),
]  # (scenario, run, obliquity): a medium and a low run at 50 m


def _eval_row(
    pipeline: str, descriptor: str, scenario: int, run: int, outcomes: list[str], **extra
):
    return {
        **_run_row(pipeline, descriptor, run, outcomes),
        "scenario": scenario,
        "noise": "none",
        "seed": 0,
        "target": "t72",
        "range_m": 50.0,
        "t_errors_m": [0.2] * outcomes.count("tp"),
        "time_per_scene_ms": 500.0,
        "stages_ms": {"match": 100.0},
        **extra,
    }


def _config(rows: list[dict]) -> dict:
    """The config.json of an `atr eval` that wrote `rows`."""
    return {
        "command": ["atr", "eval", "--jobs", "2"],
        "arms": [
            {"pipeline": p, "descriptor": d}
            for p, d in sorted({(r["pipeline"], r["descriptor"]) for r in rows})
        ],
        "flights": [
            {"scenario": s, "run": n, "noise": "none"}
            for s, n in sorted({(r["scenario"], r["run"]) for r in rows})
        ],
    }


def _sfm_and_lidar(sfm_hits: int, lidar_hits: int, scenes: int = 20) -> list[dict]:
    """GFTT SfM and LIDAR with SHOT on the same scenes, each finding the target in its first `*_hits`
    scenes of every run and missing it in the rest."""
    rows = []
    for scenario, run_, obliquity in PAPER_RUNS:
        for pipeline, hits in (("gftt-sfm", sfm_hits), ("lidar", lidar_hits)):
            outcomes = ["tp"] * hits + ["fn"] * (scenes - hits)
            rows.append(
                _eval_row(pipeline, "shot", scenario, run_, outcomes, obliquity_deg=obliquity)
            )
    return rows


def _verdict_of(rows: list[dict], claim_start: str, configs: list[dict] | None = None):
    [found] = [
        v for v in verdicts(rows, configs or [_config(rows)]) if v.claim.startswith(claim_start)
    ]
    return found


def test_the_verdicts_follow_the_rows():
    # SfM finds every target, LIDAR a third of them: the paper's "SfM outperforms LIDAR" holds
    sfm_ahead = _sfm_and_lidar(sfm_hits=20, lidar_hits=6)
    overall = _verdict_of(sfm_ahead, "Overall, SfM")
    assert overall.verdict == HOLDS
    assert overall.ours.startswith("gftt-sfm/shot 100.0% vs lidar/shot")
    assert float(overall.interval.split()[0]) > 0
    assert overall.sources == (1,)
    # the same scenes with the arms swapped: it does not
    lidar_ahead = _sfm_and_lidar(sfm_hits=6, lidar_hits=20)
    assert _verdict_of(lidar_ahead, "Overall, SfM").verdict == DOES_NOT
    # one scene apart on 40: the interval straddles 0, so the order is not shown and a tie holds
    close = _sfm_and_lidar(sfm_hits=19, lidar_hits=20)
    assert _verdict_of(close, "Overall, SfM").verdict == NOT_SHOWN
    assert _verdict_of(close, "SfM and LIDAR 3D ATR perform equally well at 50 m").verdict == HOLDS
    assert _verdict_of(sfm_ahead, "SfM and LIDAR 3D ATR perform equally").verdict == DOES_NOT
    # the paper's 98 % at medium obliquity (30°): reached by 20 of 20, missed by 6 of 20
    assert _verdict_of(sfm_ahead, "SfM GFTT F1 at medium").verdict == HOLDS
    medium = _verdict_of(lidar_ahead, "SfM GFTT F1 at medium")
    assert medium.verdict == DOES_NOT and medium.paper == "98.0%"
    assert medium.ours == "46.2% (gftt-sfm/shot)"


def test_each_claim_names_the_results_whose_rows_it_reads():
    rows = _sfm_and_lidar(sfm_hits=20, lidar_hits=6)
    sfm = [r for r in rows if r["pipeline"] == "gftt-sfm"]
    lidar = [r for r in rows if r["pipeline"] == "lidar"]
    configs = [_config(lidar), _config(sfm)]
    assert _verdict_of(rows, "Overall, SfM", configs).sources == (1, 2)
    assert _verdict_of(rows, "SfM GFTT F1 at low", configs).sources == (2,)
    section = "\n".join(_verdict_section(rows, configs))
    assert "| C1 | `atr eval --jobs 2` |" in section and "| C2 |" in section


def test_template_storage_is_counted_like_for_like():
    def row(pipeline: str, descriptor: str, kb: float) -> dict:
        return _eval_row(
            pipeline, descriptor, 1, 1, ["tp"], obliquity_deg=30.0, template_storage_kb=kb
        )

    # our whole 24-view template outweighs the 2D one, one descriptor vector as the paper counts does not
    whole = [row("gftt-sfm", "shot", 7528.5), row("2d-1", "gftt+freak", 398.0)]
    storage = _verdict_of(whole, "3D templates need less storage")
    assert storage.verdict == COUNTED_DIFFERENTLY
    assert "one 3D descriptor as the paper counts: 2.89–2.9 KB" in storage.ours
    assert _verdict_of([row("gftt-sfm", "shot", 2.9), whole[1]], "3D templates").verdict == HOLDS
    # the paper's convention reproduces its own Table V, to the digits it prints
    for descriptor in ("shot", "usc", "3dsc", "fpfh", "rops", "hod", "hod-s"):
        digits = len(str(PAPER_TABLE_V_STORAGE_KB[descriptor]).split(".")[1])
        assert round(paper_template_kb(descriptor), digits) == PAPER_TABLE_V_STORAGE_KB[descriptor]


def test_the_verdict_rules():
    assert level_verdict(98.0, 99.0, 100.0) == HOLDS
    assert level_verdict(98.0, 93.5, 98.0) == NOT_SHOWN  # the interval just reaches it
    assert level_verdict(98.0, 93.5, 97.9) == DOES_NOT
    assert bound_verdict(0.51, 0.40, 0.30) == HOLDS
    assert bound_verdict(0.51, 0.90, 0.38) == NOT_SHOWN
    assert bound_verdict(0.51, 0.90, 0.60) == DOES_NOT
    assert order_verdict(0.01, 0.2) == HOLDS and order_verdict(-0.2, -0.01) == DOES_NOT
    assert order_verdict(-0.1, 0.1) == NOT_SHOWN
    assert tie_verdict(-0.1, 0.1) == HOLDS and tie_verdict(0.01, 0.1) == DOES_NOT


def test_median_interval_holds_the_median_and_orders_a_difference():
    rng = np.random.default_rng(5)
    small, large = rng.normal(0.2, 0.05, 30), rng.normal(0.6, 0.05, 30)
    low, high = median_interval(small)
    assert low <= float(np.median(small)) <= high
    assert median_interval(small) == (low, high)  # seeded: the same interval every time
    assert median_interval(large, small)[0] > 0 > median_interval(small, large)[1]
    assert all(math.isnan(x) for x in median_interval([]))


def _write_result(folder: Path, rows: list[dict]) -> None:
    folder.mkdir(parents=True)
    (folder / "details.json").write_text(json.dumps({"results": rows}))
    (folder / "results.json").write_text(json.dumps({"results": []}))
    (folder / "config.json").write_text(
        json.dumps(
            _config(rows)
            | {
                "atr": {
                    "sim": {"width_px": 8, "height_px": 6, "focal_px": 10.0},
                    "pipeline": {"targets": ["t72"]},
                }
            }
        )
    )


def test_the_report_rewrites_itself_from_its_own_data_byte_for_byte(tmp_path: Path):
    out = tmp_path / "report"
    rows = _sfm_and_lidar(sfm_hits=15, lidar_hits=12)
    _write_result(out / "data" / "1-first", [r for r in rows if r["pipeline"] == "gftt-sfm"])
    _write_result(out / "data" / "2-second", [r for r in rows if r["pipeline"] == "lidar"])
    data = {p: p.read_bytes() for p in sorted((out / "data").rglob("*.json"))}
    args = argparse.Namespace(results=sorted((out / "data").iterdir()), out=out, example=None)
    pages = []
    for _ in range(2):
        assert run(args) == 0
        pages.append({name: (out / name).read_bytes() for name in ("README.md", "details.md")})
        # the committed results are both the input and the copy: they survive, byte for byte
        assert {p: p.read_bytes() for p in sorted((out / "data").rglob("*.json"))} == data
    assert pages[0] == pages[1]
    readme = pages[0]["README.md"].decode()
    assert "](details.md)" in readme and "## The paper's claims, tested" in readme
    assert "code version" not in readme


def test_the_committed_readme_reads_in_minutes():
    readme = (REPO / "docs" / "evaluation" / "README.md").read_text()
    assert len(readme.split()) < 2000
    # the verdicts come first, then which arm to use
    headings = [line for line in readme.splitlines() if line.startswith("## ")]
    assert headings[:2] == [
        "## The paper's claims, tested",
        "## Which arm to use and what it costs",
    ]
    assert (REPO / "docs" / "evaluation" / "details.md").exists()


def test_a_later_result_replaces_an_earlier_ones_rows_for_the_same_arm_and_flight():
    old = [
        _eval_row("2d-1", "gftt+freak", 1, 3, ["fn"] * 4),
        _eval_row("sgm-sfm", "shot", 1, 3, ["tp"]),
    ]
    new = [_eval_row("2d-1", "gftt+freak", 1, 3, ["tp", "tp", "fn", "fn"])]
    other_seed = [_eval_row("2d-1", "gftt+freak", 1, 3, ["fp"], seed=7)]
    rows = latest_rows([old, new, other_seed])
    assert [(r["pipeline"], r["tp"], r["source"]) for r in rows] == [
        ("sgm-sfm", 1, 1),
        ("2d-1", 2, 2),  # the re-run, not the first run
        ("2d-1", 0, 3),  # another world seed is another flight
    ]


def test_navigation_errors_are_compared_arm_by_arm_on_the_same_scenes():
    exact = [
        _eval_row("sgm-sfm", "shot", 1, 3, ["tp"] * 9 + ["fn"], nav_error_median_m=0.0),
        _eval_row(
            "sgm-sfm", "shot", 2, 3, ["tp"] * 10, nav_error_median_m=0.0
        ),  # not flown with nav
    ]
    nav = [
        _eval_row(
            "sgm-sfm", "shot", 1, 3, ["tp"] * 7 + ["fn"] * 3, noise="nav", nav_error_median_m=1.7
        )
    ]
    text = "\n".join(_navigation_section(exact + nav))
    (row,) = [line for line in text.splitlines() if line.startswith("| sgm-sfm/shot")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == "1"  # only the run flown both ways
    assert cells[2].startswith("94.7% (9/0/1)") and cells[3].startswith("82.4% (7/0/3)")
    assert cells[5] == "0.00 / 1.70"
    assert _navigation_section(exact) == []  # nothing to compare without a nav row


def _gftt_freak_row(
    scenario: int, run_: int, obliquity: float, outcomes: list[str], **extra: object
) -> dict:
    return _eval_row(
        "2d-1", "gftt+freak", scenario, run_, outcomes, obliquity_deg=obliquity, **extra
    )


def test_scaled_2d_templates_are_an_arm_of_their_own_never_the_papers_2d():
    single = ["tp"] * 3 + ["fn"] * 17
    scaled = ["tp"] * 15 + ["fn"] * 5
    rows = _sfm_and_lidar(sfm_hits=20, lidar_hits=6)
    for scenario, run_, obliquity in PAPER_RUNS:
        rows.append(_gftt_freak_row(scenario, run_, obliquity, single))
        rows.append(
            _gftt_freak_row(scenario, run_, obliquity, scaled, template_scales=[1.0, 0.5, 0.25])
        )
    assert {arm_label(r) for r in rows if r["pipeline"] == "2d-1"} == {
        "2d-1/gftt+freak",
        "2d-1/gftt+freak scaled",
    }
    assert len(latest_rows([rows])) == len(rows)  # neither replaces the other
    medium = _verdict_of(rows, "2D ATR (best pair) F1 at medium")
    assert medium.ours.endswith(
        "(2d-1/gftt+freak)"
    )  # the single-size templates, not the better scaled


def test_a_report_with_scaled_2d_templates_is_written_whole(tmp_path: Path):
    out = tmp_path / "report"
    rows = _sfm_and_lidar(sfm_hits=15, lidar_hits=12)
    for scenario, run_, obliquity in PAPER_RUNS:
        for scales, kb in (([1.0], 400.0), ([1.0, 0.5, 0.25], 5000.0)):
            outcomes = ["tp"] * 3 + ["fn"] * 2
            rows.append(
                _gftt_freak_row(
                    scenario,
                    run_,
                    obliquity,
                    outcomes,
                    template_scales=scales,
                    template_storage_kb=kb,
                )
            )
    _write_result(out / "data" / "1-all", rows)
    args = argparse.Namespace(results=[out / "data" / "1-all"], out=out, example=None)
    assert run(args) == 0
    details = (out / "details.md").read_text()
    # the scaled arm has its own compactness row (its descriptor is FREAK's 64 bytes) ...
    assert "| 2d-1/gftt+freak scaled | 75.0% | 64 |" in details
    # ... and the paper's 2D storage column is compared with the single-size templates only
    sized = [
        _eval_row(pipeline, descriptor, 1, 1, ["tp"], obliquity_deg=30.0, **extra)
        for pipeline, descriptor, extra in (
            ("gftt-sfm", "shot", {"template_storage_kb": 7528.5}),
            ("2d-1", "gftt+freak", {"template_storage_kb": 400.0}),
            ("2d-1", "gftt+freak", {"template_storage_kb": 5000.0, "template_scales": [1, 0.5]}),
        )
    ]
    storage = _verdict_of(sized, "3D templates need less storage")
    assert "400" in storage.ours and "5,000" not in storage.ours, storage.ours
