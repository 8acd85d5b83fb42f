"""Grounding benchmark: the paper's recipe (as its public release implements it) against ours, same pairs.

Pairs are rendered in the MuJoCo twin (configs/scenes/grounding_bench.yaml): one object is moved with a known
motion (shift up to 40 cm, yaw up to 180 deg, tilt up to 90 deg on half the pairs), the goal depth is handed
over as an unknown affine map of depth or of disparity with 0.2 % noise, masks come from the renderer. Both
methods use the offline features.

Errors: translation = distance between the estimated and true goal position of the object's centre [mm];
rotation = angle between estimated and true rotation [deg], taken modulo what one view cannot tell apart
(box: 180 deg turns about its axes; cylinder: turns about and flips of its axis; bottle: turns about its axis;
sphere: not scored). A refused pair counts as an infinite error.

    python bench/grounding.py [--quick] --out RESULT.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
TARGETS = {
    "ours_t_median_mm": 5.0,
    "ours_t_p90_mm": 15.0,
    "ours_r_median_deg": 2.0,
    "ours_r_p90_deg": 5.0,
    "ours_ms_per_pair": 300.0,
}


def _angle(R: np.ndarray) -> float:
    return math.degrees(math.acos(float(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def rotation_error(R_est: np.ndarray, R_true: np.ndarray, R_obj0: np.ndarray, kind: str, lying: bool) -> float:
    """Angle [deg] between estimated and true rotation, modulo the object's visual symmetry (NaN: not scored)."""
    if kind == "sphere":
        return float("nan")
    if kind in ("cylinder", "bottle"):
        axis = R_obj0 @ (np.array([1.0, 0, 0]) if lying and kind == "bottle" else np.array([0, 0, 1.0]))
        c = float(np.dot(R_est @ axis, R_true @ axis))
        if kind == "cylinder":
            c = abs(c)
        return math.degrees(math.acos(np.clip(c, -1, 1)))
    group = [np.eye(3)]
    if kind == "box":
        group += [np.diag(d) for d in ((1.0, -1, -1), (-1.0, 1, -1), (-1.0, -1, 1))]
    return min(_angle(R_est.T @ R_true @ R_obj0 @ S @ R_obj0.T) for S in group)


def stats(values: list[float]) -> dict[str, float]:
    v = np.array([x for x in values if not math.isnan(x)])
    if len(v) == 0:
        return {"median": float("nan"), "p90": float("nan")}
    return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90, method="higher"))}


def make_pairs(n: int, seed: int) -> list:
    from drivers.sim import SimWorld
    from pipeline.grounding.sim_pairs import PairRenderer
    from runtime.config import load_profile

    profile = load_profile(
        REPO / "configs/sim.yaml", {"sim": {"realtime": False, "scene": "grounding_bench", "seed": seed}}
    )
    world = SimWorld(profile.sim, profile.camera)
    renderer = PairRenderer(world, camera_seed=seed)
    rng = np.random.default_rng(seed)
    names = renderer.movable()
    pairs, tries = [], 0
    while len(pairs) < n:
        tries += 1
        if tries > 50 * n:
            raise RuntimeError(f"only {len(pairs)} valid pairs in {tries} tries")
        name = names[len(pairs) % len(names)]
        tilt = 90.0 if len(pairs) % 2 else 0.0
        goal = renderer.random_goal(name, rng, 0.40, 180.0, tilt)
        if goal is None:
            continue
        pair = renderer.render(name, goal, "disparity" if (len(pairs) // 2) % 2 else "depth", rng)
        if pair is not None:
            pairs.append(pair)
    renderer.close()
    lying = {o.name: o.lying for o in world.scene.objects}
    return [(p, lying[p.object_name]) for p in pairs]


def evaluate(pair, lying: bool, motion) -> tuple[float, float]:
    if not motion.ok:
        return math.inf, math.inf
    M, c = pair.T_motion_camera, pair.centre_camera
    t_err = 1000 * float(np.linalg.norm((motion.R @ c + motion.t) - (M[:3, :3] @ c + M[:3, 3])))
    r_err = rotation_error(motion.R, M[:3, :3], pair.T_camera_object0[:3, :3], pair.object_kind, lying)
    return t_err, r_err


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="12 pairs instead of 120")
    parser.add_argument("--pairs", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    n = args.pairs or (12 if args.quick else 120)

    import torch

    from pipeline.grounding.baseline import ground_baseline
    from pipeline.grounding.ground import ground
    from pipeline.grounding.types import GroundingInput
    from pipeline.perception.offline_features import OfflineFeatures

    torch.set_num_threads(1)
    console = Console(width=160)
    t0 = time.perf_counter()
    pairs = make_pairs(n, args.seed)
    console.print(f"rendered {len(pairs)} pairs in {time.perf_counter() - t0:.1f} s")
    features = OfflineFeatures()
    load_start = os.getloadavg()[0]
    records = []
    for i, (pair, lying) in enumerate(pairs):
        inp = GroundingInput(
            pair.rgb0, pair.depth0, pair.mask0, pair.rgb1, pair.depth1, pair.depth1_kind, pair.mask1, pair.intrinsics
        )
        rec = {"pair": i, "object": pair.object_name, "kind": pair.object_kind, "depth_kind": pair.depth1_kind}
        for method, fn in (("paper", lambda x: ground_baseline(x, features)), ("ours", lambda x: ground(x, features))):
            start = time.perf_counter()
            motion = fn(inp)
            ms = 1000 * (time.perf_counter() - start)
            t_err, r_err = evaluate(pair, lying, motion)
            rec[method] = {"ok": motion.ok, "reason": motion.reason, "t_mm": t_err, "r_deg": r_err, "ms": ms}
        records.append(rec)
        console.print(
            f"{i:3d} {pair.object_name:9s} {pair.depth1_kind:9s} paper t={rec['paper']['t_mm']:8.1f} mm "
            f"r={rec['paper']['r_deg']:6.1f} deg | ours t={rec['ours']['t_mm']:7.1f} mm "
            f"r={rec['ours']['r_deg']:6.1f} deg "
            f"{rec['ours']['ms']:5.0f} ms {rec['ours']['reason'][:60]}"
        )
    summary = {}
    for method in ("paper", "ours"):
        t = stats([r[method]["t_mm"] for r in records])
        rot = stats([r[method]["r_deg"] for r in records])
        summary[method] = {
            "t_median_mm": t["median"],
            "t_p90_mm": t["p90"],
            "r_median_deg": rot["median"],
            "r_p90_deg": rot["p90"],
            "refused": sum(not r[method]["ok"] for r in records),
            "ms_per_pair": float(np.mean([r[method]["ms"] for r in records])),
        }
    o, p = summary["ours"], summary["paper"]
    measured = {
        "ours_t_median_mm": o["t_median_mm"],
        "ours_t_p90_mm": o["t_p90_mm"],
        "ours_r_median_deg": o["r_median_deg"],
        "ours_r_p90_deg": o["r_p90_deg"],
        "ours_ms_per_pair": o["ms_per_pair"],
    }
    met = {k: bool(measured[k] <= TARGETS[k]) for k in TARGETS}
    met["ours_better_than_paper_on_every_statistic"] = all(
        o[k] < p[k] for k in ("t_median_mm", "t_p90_mm", "r_median_deg", "r_p90_deg")
    )
    table = Table(title=f"Grounding on {len(records)} simulated pairs (offline features)")
    table.add_column("method")
    for col in ("t median mm", "t p90 mm", "r median deg", "r p90 deg", "refused", "ms/pair"):
        table.add_column(col, justify="right")
    for method, s in summary.items():
        table.add_row(
            method,
            *(f"{s[k]:.1f}" for k in ("t_median_mm", "t_p90_mm", "r_median_deg", "r_p90_deg")),
            str(s["refused"]),
            f"{s['ms_per_pair']:.0f}",
        )
    console.print(table)
    load = {"start": load_start, "end": os.getloadavg()[0], "cpu_count": os.cpu_count()}
    console.print(f"machine load (1 min average) {load['start']:.2f} -> {load['end']:.2f} on {load['cpu_count']} CPUs")
    console.print({k: ("met" if v else "NOT met") for k, v in met.items()})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {
        "pairs": len(records),
        "seed": args.seed,
        "summary": summary,
        "measured": measured,
        "targets": TARGETS,
        "met": met,
        "load_avg_1m": load,
        "records": records,
    }
    args.out.write_text(json.dumps(_finite(result), indent=1))


def _finite(x):
    """JSON has no infinity: refused pairs' errors are written as null."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


if __name__ == "__main__":
    main()
