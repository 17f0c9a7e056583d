"""Tuning set for the 3D ATR matcher, kept apart from the evaluation worlds, and its scoring.

The evaluation uses world seed 0 (and others chosen there); this tuning set uses seeds 101-105 (101-110 for the
larger 200 m cell below).

    python bench/tune_recognition.py make  [--cache DIR] [--seeds 101 102 ...] [--pairs 2] [--lidar-every 3]
                                           [--pair-gap N] [--keep-images]
    python bench/tune_recognition.py resfm --from DIR --cache DIR2 [--set sfm_field=value ...]
    python bench/tune_recognition.py eval  [--cache DIR] [--descriptor shot] [--source sfm|lidar]
                                           [--set field=value ...] [--scenario 1 ...] [--verbose]
                                           [--targets t72 ifv truck6x6]

``make`` renders frame pairs (k, k + pair_gap) of scenarios 1 (runs 1-4), 2 (runs 1-4) and 3 with the
simulator exactly as ``simulate_flight`` does (the same world, orbit, renderer and LIDAR generator seeds),
reconstructs each pair with ``atr.sfm.reconstruct`` (true poses; the IMU poses are within millimetres) and
stores one ``.npz`` per scene in the cache folder (default: ``atr_tuning`` in the system's temporary folder).
Pairs are spread along each run so that the tuning set sees the target from all azimuths. With
``--keep-images`` the image pairs are stored too, and ``resfm`` reconstructs them again with other SfM
settings into another folder (comparing SfM settings by their effect on recognition, without rendering).

A second, larger set for the weak cells (50 and 100 m, 240 scenes; docs/recognition.md, "Roofs"):
``make --scenario 1 2 --pairs 6 --lidar-every 0 --keep-images --cache DIR``. A larger 200 m cell (40 scenes;
docs/recognition.md, "200 m on a larger sample"): ``make --scenario 3 --pairs 4 --lidar-every 0 --seeds 101
102 ... 110 --cache DIR``, and with ``--pair-gap 2`` pairs of frames two intervals apart (the second
frame within one frame of the gap-1 pair's).

``eval`` builds the templates of the T-72 and its confusers (IFV, 6x6 truck) as the template store does
(``--targets`` picks a subset, e.g. the T-72 alone), runs ``atr.recognition.recognize`` on every cached
cloud and scores it with ``atr.evaluation.metrics`` (§III-C: TP within 2 m of the T-72; FP a T-72
hypothesis without target or > 2 m off; FN none). With ``--verbose`` it prints every scene's detections
and ends with a tally of why the others failed (``why_not_true_positive``) and of what the false positives' T-72 fits sit on (an IFV, the 6x6 truck, a
car, or elsewhere; each world rebuilt without rendering).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

DEFAULT_CACHE = Path(tempfile.gettempdir()) / "atr_tuning"
RUNS: tuple[tuple[int, int], ...] = (
    (1, 1),
    (1, 2),
    (1, 3),
    (1, 4),
    (2, 1),
    (2, 2),
    (2, 3),
    (2, 4),
    (3, 1),
)
TUNING_SEEDS: tuple[int, ...] = (101, 102, 103, 104, 105)
TARGETS: tuple[str, ...] = ("t72", "ifv", "truck6x6")
# a false T-72 fit closer than this to the target is a near miss, not a confusion
NEAR_MISS_M = 10.0


# ---------------------------------------------------------------------------------------------- make


def _render_pair(world, scen, seq_a: int, gap: int, lidar: bool, seed: int, cfg):
    from atr.sim.render import Renderer, to_srgb8

    renderer = Renderer(world, cfg)
    interval = cfg.frame_interval_s(scen.range_m)
    per_frame = int(round(interval * cfg.imu_rate_hz))
    out = []
    for seq in (seq_a, seq_a + gap):
        t = seq * per_frame / cfg.imu_rate_hz
        st = world.orbit.state(np.array([t]))
        T_world_imu = np.eye(4)
        T_world_imu[:3, :3] = st.R_world_imu[0]
        T_world_imu[:3, 3] = st.p_world[0]
        T_world_cam = T_world_imu @ cfg.T_imu_cam_matrix
        lin, _ = renderer.render(T_world_cam)
        cloud = None
        if lidar and seq != seq_a:
            lrng = np.random.default_rng([seed, scen.scenario, scen.run, 3, seq])
            cloud = renderer.lidar_scan(T_world_cam, scen.lidar_resolution_m, scen.range_m, lrng)
        out.append((to_srgb8(lin), T_world_cam, renderer.visible_fraction(T_world_cam), cloud))
    return out


def make(args: argparse.Namespace) -> None:
    from atr.sfm import SfmConfig, reconstruct
    from atr.sim.config import SimConfig
    from atr.sim.scenarios import scenario
    from atr.sim.world import build_world

    cfg = SimConfig()
    sfm_cfg = SfmConfig() if args.pair_gap is None else SfmConfig(pair_gap_frames=args.pair_gap)
    gap = sfm_cfg.pair_gap_frames
    args.cache.mkdir(parents=True, exist_ok=True)
    n_done = 0
    jobs = [(seed, s, r) for seed in args.seeds for (s, r) in RUNS if s in args.scenario]
    if args.shard is not None:
        i, n = args.shard
        jobs = jobs[i::n]
    for seed, s, r in jobs:
        scen = scenario(s, r)
        names = [args.cache / f"s{seed}_sc{s}_r{r}_p{p}.npz" for p in range(args.pairs)]
        if all(n.exists() for n in names):
            continue
        t0 = time.perf_counter()
        world = build_world(scen, seed, config=cfg)
        # spread the pairs over the run, offset per seed so the azimuths differ between worlds
        offset = ((seed * 0.618034) % 1.0) / args.pairs
        for p, name in enumerate(names):
            if name.exists():
                continue
            seq_a = int((offset + p / args.pairs) * (scen.n_frames - gap - 1))
            lidar = args.lidar_every > 0 and (p + seed) % args.lidar_every == 0
            (img_a, T_a, vis_a, _), (img_b, T_b, vis_b, lid) = _render_pair(
                world, scen, seq_a, gap, lidar, seed, cfg
            )
            cloud = reconstruct(img_a, img_b, cfg.K, T_a, T_b, sfm_cfg)
            T_wt = world.T_world_target
            rel = np.linalg.inv(T_wt) @ T_b
            az_deg = float(np.degrees(np.arctan2(rel[1, 3], rel[0, 3])))
            data = {
                "sfm_points_m": np.asarray(cloud.points_world_m, np.float32),
                "sfm_sigma_m": np.asarray(cloud.sigma_m, np.float32),
                "viewpoint_m": T_b[:3, 3].astype(np.float64),
                "T_world_target": T_wt.astype(np.float64),
                "visible_fraction": np.array([vis_a, vis_b]),
                "meta": np.array(
                    json.dumps(
                        {
                            "seed": seed,
                            "scenario": s,
                            "run": r,
                            "seq_b": seq_a + gap,
                            "obliquity_deg": scen.obliquity_deg,
                            "range_m": scen.range_m,
                            "azimuth_in_target_deg": az_deg,
                            "sfm_reason": cloud.reason,
                        }
                    )
                ),
            }
            if lid is not None:
                data["lidar_points_m"] = np.asarray(lid, np.float32)
            if args.keep_images:
                data |= {"image_a": img_a, "image_b": img_b, "T_a": T_a, "T_b": T_b, "K": cfg.K}
            np.savez_compressed(name, **data)
            n_done += 1
            print(
                f"{name.name}: {len(cloud.points_world_m)} sfm points, vis {vis_b:.2f}, az {az_deg:.0f}, "
                f"lidar {0 if lid is None else len(lid)}, {time.perf_counter() - t0:.1f} s",
                flush=True,
            )
    print(f"made {n_done} scenes")


def resfm(args: argparse.Namespace) -> None:
    """Reconstruct every scene of --from (made with --keep-images) again with SfmConfig overrides."""
    from atr.sfm import SfmConfig, reconstruct

    sfm_cfg = SfmConfig(**parse_sets(args.set))
    args.cache.mkdir(parents=True, exist_ok=True)
    paths = sorted(args.source_cache.glob("s*_sc*_r*_p*.npz"))
    if args.shard is not None:
        paths = paths[args.shard[0] :: args.shard[1]]
    for path in paths:
        with np.load(path) as z:
            data = {k: z[k] for k in z.files}
        if "image_a" not in data:
            raise SystemExit(f"{path.name} has no images; make it with --keep-images")
        cloud = reconstruct(
            data["image_a"], data["image_b"], data["K"], data["T_a"], data["T_b"], sfm_cfg
        )
        data["sfm_points_m"] = np.asarray(cloud.points_world_m, np.float32)
        data["sfm_sigma_m"] = np.asarray(cloud.sigma_m, np.float32)
        for key in ("image_a", "image_b"):  # the new cache keeps clouds only
            data.pop(key)
        np.savez_compressed(args.cache / path.name, **data)
        print(f"{path.name}: {len(cloud.points_world_m)} sfm points", flush=True)


# ---------------------------------------------------------------------------------------------- eval


def load_scenes(cache: Path, scenarios: list[int], source: str) -> list[dict]:
    scenes = []
    for path in sorted(cache.glob("s*_sc*_r*_p*.npz")):
        with np.load(path) as z:
            meta = json.loads(str(z["meta"]))
            if meta["scenario"] not in scenarios:
                continue
            key = "sfm_points_m" if source == "sfm" else "lidar_points_m"
            if key not in z.files:
                continue
            scenes.append(
                {
                    "name": path.stem,
                    "points": z[key].astype(np.float64),
                    "sigma": z["sfm_sigma_m"].astype(np.float64)
                    if source == "sfm" and "sfm_sigma_m" in z.files
                    else None,
                    "viewpoint": z["viewpoint_m"],
                    "T_world_target": z["T_world_target"],
                    "visible": z["visible_fraction"],
                    "meta": meta,
                }
            )
    return scenes


def build_templates(config, descriptor: str, targets: tuple[str, ...] = TARGETS) -> list:
    import hashlib
    import pickle

    from atr.recognition import build_template
    from atr.recognition.template import TEMPLATE_VERSION
    from atr.sim.vehicles import VEHICLES

    cfg = dataclasses.replace(config, descriptor=descriptor)
    key = hashlib.sha256(repr((cfg.template, TEMPLATE_VERSION, targets)).encode()).hexdigest()[:16]
    path = DEFAULT_CACHE / "templates" / f"{descriptor}-{key}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    out = []
    for t in targets:
        mesh = VEHICLES[t]()
        out.append(build_template(mesh.vertices, mesh.triangles, t, descriptor, cfg))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(out))
    return out


def parse_sets(items: list[str]) -> dict:
    import yaml

    out = {}
    for item in items:
        k, v = item.split("=", 1)
        val = yaml.safe_load(v)
        out[k] = tuple(val) if isinstance(val, list) else val
    return out


def _vehicle_under_best(detections: list, meta: dict, vehicles: dict[tuple, tuple]) -> str:
    """The vehicle the best T-72 detection sits on (its world rebuilt once per run and kept in
    ``vehicles``), or the report's "elsewhere"."""
    from atr.evaluation.metrics import vehicle_under
    from atr.evaluation.runner import Flight
    from atr.evaluation.tables import NOT_ON_A_VEHICLE, flight_vehicles
    from atr.sim.config import SimConfig

    key = (meta["seed"], meta["scenario"], meta["run"])
    if key not in vehicles:
        flight = Flight(meta["scenario"], meta["run"], seed=meta["seed"])
        vehicles[key] = flight_vehicles(flight, SimConfig())
    best = next(d for d in detections if d.target == "t72")
    return vehicle_under(best.T_world_target[:3, 3], *vehicles[key]) or NOT_ON_A_VEHICLE


def why_not_true_positive(
    outcome: str,
    detections: list,
    verified: list,
    T_world_target: np.ndarray | None,
    target: str = "t72",
) -> str:
    """Why a scene that has the target, or reports it, is not a true positive: the first of these
    that holds (docs/recognition.md, "Where the dense arm's errors come from"); "" for TP and TN.

    Args:
        outcome: the scene's outcome ("tp", "fp", "fn", "tn").
        detections: the matcher's detections, best first.
        verified: the matcher's ``stats["verified"]``: every hypothesis ICP refined, accepted or
            not, as (target, view, overlap, overlap vertices, clutter, x, y, z, ...).
        T_world_target: (4, 4) pose of the target in the scene; None when it is not there.
        target: the target's template name.

    """
    from atr.evaluation.metrics import MAX_TRANSLATION_ERROR_M

    if outcome in ("tp", "tn"):
        return ""
    if T_world_target is None:
        return "reported without target"
    true_m = np.asarray(T_world_target, np.float64)[:3, 3]

    def off_m(position_m) -> float:
        return float(np.linalg.norm(np.asarray(position_m, np.float64) - true_m))

    def near(position_m) -> bool:
        return off_m(position_m) < MAX_TRANSLATION_ERROR_M

    if outcome == "fp":
        best = next(d for d in detections if d.target == target)
        if off_m(best.T_world_target[:3, 3]) < NEAR_MISS_M:
            return f"T-72 fit {MAX_TRANSLATION_ERROR_M:g}-{NEAR_MISS_M:g} m off"
    if any(d.target == target and near(d.T_world_target[:3, 3]) for d in detections):
        return "a true fit scores under a T-72 fit elsewhere"
    if any(d.target != target and near(d.T_world_target[:3, 3]) for d in detections):
        return "another template holds the target's place"
    if any(h[0] == target and near(h[5:8]) for h in verified):
        return "true hypothesis refused by verification"
    return "no T-72 hypothesis within 2 m of the target"


def evaluate(scenes: list[dict], templates: list, config, verbose: bool = False) -> dict:
    from atr.evaluation.metrics import count, score_scene
    from atr.recognition import lowest_per_cell, recognize, terrain_height_at, uniform_subsample
    from atr.sim.config import SimConfig

    present = SimConfig().present_min_visible_fraction
    per: dict[str, list] = {}
    times: list[float] = []
    stage_sum: dict[str, list[float]] = {}
    errors = []
    # verbose: each T-72 detection's base height above the terrain as the matcher's roof rule
    # estimates it (docs/recognition.md, "Roofs"), by outcome
    above_terrain: dict[bool, list[float]] = {True: [], False: []}
    hypotheses = [0, 0]  # from RANSAC, and verified (repeats of one view dropped)
    causes: Counter[str] = Counter()  # verbose: why scenes are not true positives, by outcome
    fp_on: Counter[str] = Counter()  # verbose: what the false positives' best T-72 fit sits on
    vehicles: dict[tuple, tuple] = {}  # each world's non-target vehicles, by (seed, scenario, run)
    for sc in scenes:
        res = recognize(
            sc["points"],
            templates,
            config,
            seed=sc["meta"]["seq_b"],
            viewpoint_m=sc["viewpoint"],
            scene_sigma_m=sc["sigma"],
        )
        times.append(res.stage_times_ms["total"])
        for per_template in res.stats.get("templates", []):
            hypotheses[0] += per_template["hypotheses"]
            hypotheses[1] += per_template["distinct_hypotheses"]
        for k, v in res.stage_times_ms.items():
            stage_sum.setdefault(k, []).append(v)
        has = sc["visible"][1] >= present
        truth = [sc["T_world_target"][:3, 3]] if has else []
        hyps = [d.T_world_target[:3, 3] for d in res.detections if d.target == "t72"]
        s = score_scene(truth, hyps)
        m = sc["meta"]
        key = f"sc{m['scenario']} {m['range_m']:.0f}m {m['obliquity_deg']:.0f}deg"
        per.setdefault(key, []).append(s)
        if s.outcome == "tp":
            errors.append(s.translation_error_m)
        if verbose:
            surface = sc["points"][uniform_subsample(sc["points"], config.resolution_m)]
            cells = lowest_per_cell(surface, config.k_ground_cell * config.resolution_m)
            parts = []
            for d in res.detections:
                off_m = float(np.linalg.norm(d.T_world_target[:3, 3] - sc["T_world_target"][:3, 3]))
                up_m = float(
                    d.T_world_target[2, 3]
                    - terrain_height_at(
                        *cells,
                        d.T_world_target[:2, 3],
                        config.terrain_window_m,
                        config.ground_percentile,
                    )[0]
                )
                if d.target == "t72":
                    above_terrain[has and off_m < 2.0].append(up_m)
                parts.append(f"{d.target}:{d.score:.0f}/{d.overlap:.2f}@{off_m:.1f}m^{up_m:+.1f}m")
            det = ", ".join(parts)
            # the roof rule's terrain under the true T-72, and the points sunk more than 3 m under its
            # base (docs/sfm.md, "The search reaches the ground")
            T_true = sc["T_world_target"]
            terrain_m = terrain_height_at(
                *cells, T_true[:2, 3], config.terrain_window_m, config.ground_percentile
            )[0]
            sunk = int(np.count_nonzero(sc["points"][:, 2] < T_true[2, 3] - 3.0))
            why = why_not_true_positive(
                s.outcome,
                res.detections,
                res.stats.get("verified", []),
                T_true if has else None,
            )
            if why:
                causes[f"{s.outcome}: {why}"] += 1
            if s.outcome == "fp":
                fp_on[_vehicle_under_best(res.detections, m, vehicles)] += 1
            print(
                f"  {sc['name']:22} {s.outcome:2} pts {len(sc['points']):6d} kp {res.stats.get('keypoints', 0):5d}"
                f" vis {sc['visible'][1]:.2f} az {m['azimuth_in_target_deg']:5.0f}"
                f" terrain {terrain_m - T_true[2, 3]:+6.2f} m sunk {sunk:5d}"
                f" {res.stage_times_ms['total']:6.0f} ms  [{det}]" + (f"  ({why})" if why else ""),
                flush=True,
            )
    if verbose and above_terrain[True]:
        from atr.recognition import RecognitionConfig

        step_m = RecognitionConfig(
            resolution_m=config.resolution_m
        ).terrain_step_m  # the default rule
        wrong = np.array(above_terrain[False])
        print(
            f"  T-72 base above the terrain: {len(above_terrain[True])} TPs "
            f"{min(above_terrain[True]):+.2f} to {max(above_terrain[True]):+.2f} m; "
            f"{np.count_nonzero(wrong > step_m)} of {len(wrong)} others above {step_m:.2f} m"
            + (f" (up to {wrong.max():+.2f} m)" if len(wrong) else ""),
            flush=True,
        )
    if verbose:
        for cause, n in causes.most_common():
            print(f"  {n:4d}  {cause}", flush=True)
        on = ", ".join(f"{name} {n}" for name, n in fp_on.most_common())
        print(f"  false positives on: {on or 'none'}", flush=True)
    all_scores = [s for v in per.values() for s in v]
    return {
        "per": {
            k: dataclasses.asdict(count(v)) | {"f1": count(v).f1} for k, v in sorted(per.items())
        },
        "all": dataclasses.asdict(count(all_scores)) | {"f1": count(all_scores).f1},
        "t_error_median_m": float(np.median(errors)) if errors else float("nan"),
        "time_median_ms": float(statistics.median(times)) if times else float("nan"),
        "stages_median_ms": {k: float(statistics.median(v)) for k, v in stage_sum.items()},
        "hypotheses": hypotheses[0],
        "hypotheses_verified": hypotheses[1],
    }


def eval_cmd(args: argparse.Namespace) -> None:
    from atr.recognition import RecognitionConfig

    config = dataclasses.replace(
        RecognitionConfig(descriptor=args.descriptor), **parse_sets(args.set)
    )
    scenes = load_scenes(args.cache, args.scenario, args.source)
    if args.limit:
        scenes = scenes[: args.limit]
    t = time.perf_counter()
    templates = build_templates(config, args.descriptor, tuple(args.targets))
    print(
        f"{len(templates)} templates in {time.perf_counter() - t:.1f} s; {len(scenes)} scenes "
        f"({args.source}, {args.descriptor}) {' '.join(args.set)}",
        flush=True,
    )
    s = evaluate(scenes, templates, config, args.verbose)
    for k, v in s["per"].items():
        print(
            f"  {k:20} tp {v['tp']:3d} fp {v['fp']:3d} fn {v['fn']:3d} tn {v['tn']:3d}  F1 {v['f1']:.3f}"
        )
    a = s["all"]
    print(
        f"  ALL                  tp {a['tp']:3d} fp {a['fp']:3d} fn {a['fn']:3d} tn {a['tn']:3d}  F1 {a['f1']:.3f}"
        f"  t_err {s['t_error_median_m']:.2f} m  time {s['time_median_ms']:.0f} ms"
    )
    print("  stages " + " ".join(f"{k} {v:.0f}" for k, v in s["stages_median_ms"].items()))
    print(f"  hypotheses {s['hypotheses']}, verified {s['hypotheses_verified']}")
    if args.json:
        Path(args.json).write_text(json.dumps(s, indent=1))


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = ap.add_subparsers(dest="cmd", required=True)
    mk = sub.add_parser("make")
    mk.add_argument("--cache", type=Path, default=DEFAULT_CACHE)
    mk.add_argument("--seeds", type=int, nargs="+", default=list(TUNING_SEEDS))
    mk.add_argument("--scenario", type=int, nargs="+", default=[1, 2, 3])
    mk.add_argument("--pairs", type=int, default=2, help="frame pairs per run")
    mk.add_argument(
        "--lidar-every", type=int, default=3, help="a LIDAR scan with every n-th pair (0: none)"
    )
    mk.add_argument("--shard", type=int, nargs=2, default=None, metavar=("I", "N"))
    mk.add_argument(
        "--pair-gap",
        type=int,
        default=None,
        help="frames between the two views of a pair (default: SfmConfig.pair_gap_frames)",
    )
    mk.add_argument(
        "--keep-images", action="store_true", help="store the image pairs too (for resfm)"
    )
    rs = sub.add_parser("resfm")
    rs.add_argument("--from", dest="source_cache", type=Path, required=True)
    rs.add_argument("--cache", type=Path, required=True)
    rs.add_argument(
        "--set", nargs="*", action="extend", default=[], help="SfmConfig overrides field=value"
    )
    rs.add_argument("--shard", type=int, nargs=2, default=None, metavar=("I", "N"))
    ev = sub.add_parser("eval")
    ev.add_argument("--cache", type=Path, default=DEFAULT_CACHE)
    ev.add_argument("--descriptor", default="shot")
    ev.add_argument("--source", choices=("sfm", "lidar"), default="sfm")
    ev.add_argument("--scenario", type=int, nargs="+", default=[1, 2, 3])
    ev.add_argument(
        "--set",
        nargs="*",
        action="extend",
        default=[],
        help="RecognitionConfig overrides field=value",
    )
    ev.add_argument(
        "--targets",
        nargs="+",
        default=list(TARGETS),
        choices=TARGETS,
        help="templates to match (default: the T-72 and its confusers); the T-72 is scored",
    )
    ev.add_argument("--limit", type=int, default=0)
    ev.add_argument("--verbose", action="store_true")
    ev.add_argument("--json", default="")
    args = ap.parse_args()
    if any(s in (0,) for s in getattr(args, "seeds", [])):
        print("seed 0 is the evaluation world; the tuning set must not use it", file=sys.stderr)
        return 2
    {"make": make, "resfm": resfm, "eval": eval_cmd}[args.cmd](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
