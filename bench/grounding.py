"""Grounding benchmark: ours against the paper's recipe (as its public release implements it) on two sets of pairs.

- mujoco: pairs rendered in the project's MuJoCo twin (configs/scenes/grounding_bench.yaml, the scenes the method
  grew up on): one object moved with a known motion (shift up to 40 cm, yaw up to 180 deg, tilt 90 deg on half),
  the goal depth an unknown affine map of depth or disparity with 0.2 % noise, masks from the renderer.
- raycast: pairs from bench/pairgen, an independent generator sharing nothing with the project's renderer or
  scenes: its own meshes (boxes, cylinders, bottles, mugs, bowls, pans, plates, balls), procedural textures and
  decals, lighting and shadows, slides, in-place turns and tips up to 90 deg; the goal image drifted the way an
  editor drifts it, the goal depth corrupted the way a monocular model does (edges bled, a slow warp, ~1 % noise,
  an affine map in depth or disparity), masks with a segmenter's errors.

Errors: translation = distance between where the estimated and the true motion put the object's centre [mm];
rotation = the angle left after the turns of the symmetry the generator knows as truth are taken out (what the
goal view cannot show: bench/pairgen/scoring.py), and, for ours, the turns of the symmetry it reports with its motion
(pipeline/grounding/seen_symmetry.py), never beyond the shape's own: the issue's targets are on that figure, and
the error modulo the true symmetry alone is reported beside it (`r_true_*`). A refused pair counts as an infinite
error. A ball is not scored for rotation.

The refusal: every pair's true motion and its twins under the true symmetry and under its shape's (ground() judges
its registration before it reads which of the shape's twins a print shows: seen_turns.py), handed to ground()'s own
selection as its only hypotheses (ICP polish and view agreement, bench/true_motion.py), gets the score ground() refuses
below (min_view_score); the report gives that distribution, the share of true motions the threshold would refuse,
how many of our accepted answers are wrong (beyond 20 mm or 10 deg), how many answers the agreement check refused
and of those how many would have been right (ground() again with no threshold: the truth's own score, taken where
the model's goal depth puts the object, can fall under the threshold where ground()'s answer, moved afterwards by
the outline and the support, is right). Each of our failures is put down to a cause by the true motion's score:
the score refuses the truth too (refused, the truth under the threshold), the score prefers a wrong motion (wrong,
or refused while the truth would pass, and the truth ranks no higher than the answer on what ground() chooses by:
select.Selected.ranked, seen points with colour as a tie-break, not the refusal's score), the search missed it (the
truth ranks higher), or another refusal (too few inliers, a residual, the depth fit).

What each corruption costs: `--without bleed,warp,noise` (any of bench/pairgen/corrupt.CORRUPTIONS) makes the raycast
set's very pairs with those corruptions left out, every other draw the same: the gain over a run without it is what
that corruption costs (left out together, the depth model's bled edges, warp and noise cost 12 of 120 right answers
at 3d2c71d, none of them alone more than 1).

Timing: wall and CPU time per pair, for ours and the paper's recipe in the same run, and a fixed reference
workload timed at the start and the end, so figures can be compared across loads (`ms / reference`).

    python bench/grounding.py [--quick] [--sets mujoco,raycast] [--seed S] [--raycast-seed S] [--without C,...]
        --out RESULT.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

REPO = Path(__file__).resolve().parents[1]
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(REPO))

from bench.pairgen.corrupt import CORRUPTIONS  # noqa: E402

TARGETS = {
    "accepted_fraction": 0.95,
    "t_median_mm": 3.0,
    "t_p90_mm": 10.0,
    "r_median_deg": 2.0,
    "r_p90_deg": 5.0,
    "ms_per_pair": 300.0,
    "true_motion_refused_fraction": 0.01,
}
WRONG_MM, WRONG_DEG = 20.0, 10.0  # an accepted answer beyond either is wrong and should have been refused


def reference_workload() -> float:
    """Seconds for a fixed mix of what grounding spends its time on (batched small matmuls, gathers, an image
    filter), single-threaded: the yardstick that makes timings comparable across machine loads."""
    import cv2

    rng = np.random.default_rng(0)
    R = rng.normal(size=(2000, 3, 3)).astype(np.float32)
    P = rng.normal(size=(3, 300)).astype(np.float32)
    img = rng.random((360, 640)).astype(np.float32)
    idx = rng.integers(0, img.size, (2000, 300))
    start = time.perf_counter()
    for _ in range(5):
        X = np.matmul(R, P)
        np.exp(-0.5 * X * X).sum()
        img.ravel()[idx].sum()
        cv2.GaussianBlur(img, (0, 0), 2.0)
    return time.perf_counter() - start


def stats(values: list[float]) -> dict[str, float]:
    v = np.array([x for x in values if not math.isnan(x)], dtype=np.float64)
    if len(v) == 0:
        return {"median": float("nan"), "p90": float("nan"), "n": 0}
    return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90, method="higher")), "n": len(v)}


def motion_kind(T: np.ndarray, T_base_camera: np.ndarray, centre: np.ndarray) -> str:
    """slide, turn (in place: the object's centre moves under 2 cm across the table) or tip, from the true motion.
    The shift is the centre's, not the base-frame motion's translation, which a turn far from the base's origin
    makes large."""
    R_base = T_base_camera[:3, :3]
    tilt = math.degrees(math.acos(float(np.clip((R_base @ T[:3, :3] @ R_base.T)[2, 2], -1.0, 1.0))))
    if tilt > 15.0:
        return "tip"
    shift = R_base @ (T[:3, :3] @ centre + T[:3, 3] - centre)
    return "turn" if np.linalg.norm(shift[:2]) < 0.02 else "slide"


# -- the two sets -------------------------------------------------------------------------------------------


def mujoco_pairs(n: int, seed: int) -> list[dict]:
    """The MuJoCo twin's pairs, with their truth (the symmetry each object kind has by construction)."""
    from bench.pairgen.generate import TrueSymmetry
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
    lying = {o.name: o.lying for o in world.scene.objects}
    out, tries = [], 0
    while len(out) < n:
        tries += 1
        if tries > 50 * n:
            raise RuntimeError(f"only {len(out)} valid pairs in {tries} tries")
        name = names[len(out) % len(names)]
        tilt = 90.0 if len(out) % 2 else 0.0
        goal = renderer.random_goal(name, rng, 0.40, 180.0, tilt)
        if goal is None:
            continue
        pair = renderer.render(name, goal, "disparity" if (len(out) // 2) % 2 else "depth", rng)
        if pair is None:
            continue
        kind = pair.object_kind
        half_turns = np.array([np.eye(3), np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])])
        axis = np.array([1.0, 0, 0]) if (kind == "bottle" and lying[name]) else np.array([0, 0, 1.0])
        truth = {
            "box": TrueSymmetry(half_turns),
            "cylinder": TrueSymmetry(np.eye(3)[None], axis=axis, flip=True),
            "bottle": TrueSymmetry(np.eye(3)[None], axis=axis),
            "sphere": TrueSymmetry(np.eye(3)[None], ball=True),
        }.get(kind, TrueSymmetry(np.eye(3)[None]))
        out.append({"pair": pair, "kind": {"sphere": "ball"}.get(kind, kind), "truth": truth, "shape": truth})
    renderer.close()
    return out


def raycast_pairs(n: int, seed: int, without: frozenset[str] = frozenset()) -> list[dict]:
    from bench.pairgen.generate import make_pair

    out = []
    for i in range(n):
        p = make_pair(seed, i, without=without)
        out.append({"pair": p, "kind": p.object_kind, "truth": p.symmetry, "shape": p.shape_symmetry})
    return out


# -- one pair -----------------------------------------------------------------------------------------------


def run_pair(entry: dict, features, config) -> dict:
    from bench.pairgen.scoring import reported_rotation_error_deg, rotation_error_deg, translation_error_mm
    from bench.true_motion import true_motion_scores, true_twins
    from pipeline.grounding.baseline import ground_baseline
    from pipeline.grounding.ground import ground
    from pipeline.grounding.types import GroundingInput

    pair, truth = entry["pair"], entry["truth"]
    inp = GroundingInput(
        pair.rgb0, pair.depth0, pair.mask0, pair.rgb1, pair.depth1, pair.depth1_kind, pair.mask1, pair.intrinsics
    )
    T = pair.T_motion_camera
    R0 = pair.T_camera_object0[:3, :3]
    rec = {
        "object_kind": entry["kind"],
        "motion_kind": motion_kind(T, pair.T_base_camera, pair.centre_camera),
        "depth_kind": pair.depth1_kind,
        "true_symmetry": truth.label,
        "true_rotation_deg": _angle(T[:3, :3]),
        "true_shift_mm": 1000 * float(np.linalg.norm(T[:3, :3] @ pair.centre_camera + T[:3, 3] - pair.centre_camera)),
    }

    def errors(motion) -> dict:
        """The accepted motion's translation error, rotation error modulo the true symmetry and modulo the one it
        reports, and that symmetry."""
        reported = as_true_symmetry(motion.symmetry, R0)
        return {
            "t_mm": translation_error_mm(motion.R, motion.t, T, pair.centre_camera),
            "r_true_deg": rotation_error_deg(motion.R, T[:3, :3], R0, truth),
            "r_deg": reported_rotation_error_deg(motion.R, T[:3, :3], R0, truth, entry["shape"], reported),
            "symmetry": motion.symmetry.label if motion.symmetry is not None else "none",
        }

    for method in ("paper", "ours"):
        wall, cpu = time.perf_counter(), time.process_time()
        if method == "paper":
            motion = ground_baseline(inp, features)
        else:
            motion = ground(inp, features, config, T_base_camera=pair.T_base_camera)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        r = {"ok": motion.ok, "reason": motion.reason, "ms": 1000 * wall, "cpu_ms": 1000 * cpu}
        if motion.ok:
            r |= errors(motion)
            if method == "ours":
                r["agreement"] = motion.details.get("view_score", float("nan"))
                r["ranked"] = motion.details.get("view_ranked", float("nan"))
        else:
            r["t_mm"] = r["r_deg"] = r["r_true_deg"] = math.inf
        if method == "ours" and _refused_by_agreement(r):  # would the answer refused have been right?
            unrefused = ground(
                inp, features, config.model_copy(update={"min_view_score": 0.0}), T_base_camera=pair.T_base_camera
            )
            r["refused_answer"] = (
                errors(unrefused) | {"ranked": unrefused.details.get("view_ranked", float("nan"))}
                if unrefused.ok
                else None
            )
        rec[method] = r
    twins = true_twins(T, truth, R0, pair.centre_camera)
    if entry["shape"] is not truth:
        twins += true_twins(T, entry["shape"], R0, pair.centre_camera)
    rec["true_agreement"], rec["true_ranked"] = true_motion_scores(inp, twins, config)
    return rec


def as_true_symmetry(seen, R_obj0: np.ndarray):
    """A reported symmetry (pipeline.grounding.types.SeenSymmetry: camera frame, as first seen; None or kind none:
    nothing reported) as a TrueSymmetry in the truth's object frame, or None."""
    from bench.pairgen.generate import TrueSymmetry

    if seen is None or seen.kind == "none":
        return None
    if seen.kind == "ball":
        return TrueSymmetry(np.eye(3)[None], ball=True)
    if seen.axis is not None:
        return TrueSymmetry(np.eye(3)[None], axis=R_obj0.T @ seen.axis, flip=seen.kind == "revolution_ends_alike")
    return TrueSymmetry(np.einsum("ji,kjl,lm->kim", R_obj0, seen.rotations, R_obj0))


def _angle(R: np.ndarray) -> float:
    return math.degrees(math.acos(float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


# -- summaries ----------------------------------------------------------------------------------------------


def summarise(records: list[dict], threshold: float) -> dict:
    out = {}
    for method in ("paper", "ours"):
        t = stats([r[method]["t_mm"] for r in records])
        rot = stats([r[method]["r_deg"] for r in records])
        rot_true = stats([r[method]["r_true_deg"] for r in records])
        out[method] = {
            "pairs": len(records),
            "accepted_fraction": float(np.mean([r[method]["ok"] for r in records])) if records else float("nan"),
            "t_median_mm": t["median"],
            "t_p90_mm": t["p90"],
            "r_median_deg": rot["median"],
            "r_p90_deg": rot["p90"],
            "r_scored": rot["n"],
            "r_true_median_deg": rot_true["median"],
            "r_true_p90_deg": rot_true["p90"],
            "ms_per_pair": float(np.mean([r[method]["ms"] for r in records])),
            "cpu_ms_per_pair": float(np.mean([r[method]["cpu_ms"] for r in records])),
        }
    true_scores = np.array([r["true_agreement"] for r in records])
    ours = [r["ours"] for r in records]
    wrong = [o for o in ours if _wrong(o)]
    out["true_motion"] = {
        "agreement_percentiles": {
            str(q): float(np.percentile(true_scores, q)) for q in (0, 1, 2, 5, 10, 25, 50, 75, 90, 100)
        },
        "threshold": threshold,
        "refused_fraction": float(np.mean(true_scores < threshold)),
        "wrong_answers_accepted": len(wrong),
        "refused_by_agreement": sum(1 for o in ours if _refused_by_agreement(o)),
        "right_answers_refused": sum(
            1 for o in ours if o.get("refused_answer") and not _wrong({"ok": True, **o["refused_answer"]})
        ),
        "failure_causes": failure_causes(records, threshold),
    }
    return out


def _wrong(o: dict) -> bool:
    return o["ok"] and (o["t_mm"] > WRONG_MM or o["r_deg"] > WRONG_DEG)


def _refused_by_agreement(o: dict) -> bool:
    return not o["ok"] and "does not explain the images" in o["reason"]


def failure_causes(records: list[dict], threshold: float) -> dict[str, int]:
    """Our failures (refused or wrong) by what the true motion's scores say of them (module docstring): which of the
    truth and the answer ranks higher (Selected.ranked, what ground() chose on) tells the search's failures from the
    ranking's; a refused answer is the one ground() gives with no threshold."""
    causes = dict.fromkeys(("score_refuses_truth", "score_prefers_wrong", "search_missed", "other_refusal"), 0)
    for r in records:
        o, truth = r["ours"], r["true_ranked"]
        if o["ok"] and not _wrong(o):
            continue
        if o["ok"]:
            causes["search_missed" if truth > o["ranked"] else "score_prefers_wrong"] += 1
        elif not _refused_by_agreement(o):
            causes["other_refusal"] += 1
        elif r["true_agreement"] < threshold:
            causes["score_refuses_truth"] += 1
        else:
            answer = o.get("refused_answer")
            causes["search_missed" if answer is None or truth > answer["ranked"] else "score_prefers_wrong"] += 1
    return causes


def breakdown(records: list[dict], key: str) -> dict:
    groups: dict[str, list] = defaultdict(list)
    for r in records:
        groups[r[key]].append(r)
    return {k: {m: summarise(v, 0.0)[m] for m in ("paper", "ours")} for k, v in sorted(groups.items())}


def targets_met(summary: dict) -> dict[str, bool]:
    o, p = summary["ours"], summary["paper"]
    met = {
        "accepted_fraction": o["accepted_fraction"] >= TARGETS["accepted_fraction"],
        "t_median_mm": o["t_median_mm"] <= TARGETS["t_median_mm"],
        "t_p90_mm": o["t_p90_mm"] <= TARGETS["t_p90_mm"],
        "r_median_deg": o["r_median_deg"] <= TARGETS["r_median_deg"],
        "r_p90_deg": o["r_p90_deg"] <= TARGETS["r_p90_deg"],
        "ms_per_pair": o["ms_per_pair"] <= TARGETS["ms_per_pair"],
        "true_motion_refused_fraction": summary["true_motion"]["refused_fraction"]
        <= TARGETS["true_motion_refused_fraction"],
    }
    met["better_than_paper_on_every_statistic"] = all(
        o[k] < p[k] for k in ("t_median_mm", "t_p90_mm", "r_median_deg", "r_p90_deg")
    ) and (o["accepted_fraction"] >= p["accepted_fraction"])
    return met


def print_set(console: Console, name: str, records: list[dict], summary: dict) -> None:
    table = Table(title=f"{name}: {len(records)} pairs")
    table.add_column("group")
    for col in ("n", "accepted", "t med mm", "t p90 mm", "r med deg", "r p90 deg"):
        table.add_column(f"ours {col}" if col != "n" else col, justify="right")
    for col in ("accepted", "t med mm", "r med deg"):
        table.add_column(f"paper {col}", justify="right")

    def row(label: str, s: dict) -> None:
        o, p = s["ours"], s["paper"]
        table.add_row(
            label,
            str(o["pairs"]),
            f"{o['accepted_fraction']:.0%}",
            *(f"{o[k]:.1f}" for k in ("t_median_mm", "t_p90_mm", "r_median_deg", "r_p90_deg")),
            f"{p['accepted_fraction']:.0%}",
            f"{p['t_median_mm']:.0f}",
            f"{p['r_median_deg']:.0f}",
        )

    row("all", summary)
    for key in ("object_kind", "motion_kind"):
        for label, s in breakdown(records, key).items():
            row(f"{key.split('_')[0]}: {label}", s)
    console.print(table)
    tm = summary["true_motion"]
    pct = tm["agreement_percentiles"]
    console.print(
        f"true motion agreement: min {pct['0']:.2f}, p1 {pct['1']:.2f}, p5 {pct['5']:.2f}, median {pct['50']:.2f}; "
        f"threshold {tm['threshold']:.2f} refuses {tm['refused_fraction']:.1%} of true motions; "
        f"wrong answers accepted {tm['wrong_answers_accepted']}, answers refused by agreement "
        f"{tm['refused_by_agreement']} (of which right, had they been taken: {tm['right_answers_refused']})"
    )
    causes = tm["failure_causes"]
    console.print(
        f"our failures by cause: the score refuses the true motion too {causes['score_refuses_truth']}, prefers a "
        f"wrong motion {causes['score_prefers_wrong']}; the search missed a motion that ranks higher "
        f"{causes['search_missed']}; other refusals {causes['other_refusal']}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="12 MuJoCo and 16 raycast pairs")
    parser.add_argument("--sets", default="mujoco,raycast")
    parser.add_argument("--pairs", type=int, default=None, help="pairs per set")
    parser.add_argument("--seed", type=int, default=0, help="MuJoCo set seed")
    parser.add_argument("--raycast-seed", type=int, default=2000, help="raycast set seed")
    parser.add_argument(
        "--without", default="", help=f"raycast corruptions drawn but not done, of: {', '.join(CORRUPTIONS)}"
    )
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    sets = [s.strip() for s in args.sets.split(",") if s.strip()]
    if unknown := set(sets) - {"mujoco", "raycast"}:
        parser.error(f"unknown set(s) {sorted(unknown)}: use mujoco and/or raycast")
    without = frozenset(c.strip() for c in args.without.split(",") if c.strip())
    if unknown := without - set(CORRUPTIONS):
        parser.error(f"unknown corruption(s) {sorted(unknown)}: use any of {', '.join(CORRUPTIONS)}")

    import torch

    from pipeline.grounding.types import GroundingConfig
    from pipeline.perception.offline_features import OfflineFeatures

    torch.set_num_threads(1)
    console = Console(width=170)
    config = GroundingConfig()
    features = OfflineFeatures()
    load = {"start": os.getloadavg()[0], "cpu_count": os.cpu_count()}
    reference = [reference_workload()]
    result: dict = {"sets": {}, "targets": TARGETS, "threshold": config.min_view_score}
    for name in sets:
        n = args.pairs or (12 if name == "mujoco" else 16) if args.quick else (args.pairs or 120)
        seed = args.seed if name == "mujoco" else args.raycast_seed
        start = time.perf_counter()
        spared = sorted(without) if name == "raycast" else []
        entries = mujoco_pairs(n, seed) if name == "mujoco" else raycast_pairs(n, seed, without)
        console.print(
            f"{name}: {len(entries)} pairs made in {time.perf_counter() - start:.0f} s (seed {seed})"
            + (f", without {', '.join(spared)}" if spared else "")
        )
        records = []
        for i, entry in enumerate(entries):
            rec = run_pair(entry, features, config)
            records.append(rec)
            result["sets"][name] = {"seed": seed, "without": spared, "finished": False, "records": records}
            _write(args.out, result)  # a run stopped part way still leaves what it measured
            o, p = rec["ours"], rec["paper"]
            console.print(
                f"{name} {i:3d} {rec['object_kind']:8s} {rec['motion_kind']:5s} | paper t={p['t_mm']:7.1f} "
                f"r={p['r_deg']:6.1f} | ours t={o['t_mm']:6.1f} mm r={o['r_deg']:6.1f} deg "
                f"{o['ms']:5.0f} ms true_sym={rec['true_symmetry']:16s} ours_sym={o.get('symmetry', '-'):22s} "
                f"agree={o.get('agreement', 0):.2f} true_agree={rec['true_agreement']:.2f} {o['reason'][:50]}"
            )
        reference.append(reference_workload())
        summary = summarise(records, config.min_view_score)
        summary["by_object_kind"] = breakdown(records, "object_kind")
        summary["by_motion_kind"] = breakdown(records, "motion_kind")
        summary["met"] = targets_met(summary)
        print_set(console, name, records, summary)
        result["sets"][name] = {
            "seed": seed,
            "without": spared,
            "finished": True,
            "summary": summary,
            "records": records,
        }
        _write(args.out, result)
    load["end"] = os.getloadavg()[0]
    ref = float(np.median(reference))
    for name, s in result["sets"].items():
        o, p = s["summary"]["ours"], s["summary"]["paper"]
        s["summary"]["timing"] = {
            "ours_over_reference": o["ms_per_pair"] / (1000 * ref),
            "paper_over_reference": p["ms_per_pair"] / (1000 * ref),
            "ours_over_paper": o["ms_per_pair"] / p["ms_per_pair"],
        }
        console.print(
            f"{name}: ours {o['ms_per_pair']:.0f} ms/pair wall ({o['cpu_ms_per_pair']:.0f} ms CPU), paper "
            f"{p['ms_per_pair']:.0f} ms; ours = {o['ms_per_pair'] / (1000 * ref):.1f} reference workloads, "
            f"{o['ms_per_pair'] / p['ms_per_pair']:.2f} x the paper's recipe"
        )
        console.print({k: ("met" if v else "NOT met") for k, v in s["summary"]["met"].items()})
    result["reference_workload_s"] = reference
    result["load_avg_1m"] = load
    console.print(
        f"machine load (1 min average) {load['start']:.2f} -> {load['end']:.2f} on {load['cpu_count']} CPUs; "
        f"reference workload {1000 * min(reference):.0f}-{1000 * max(reference):.0f} ms"
    )
    _write(args.out, result)


def _write(path: Path, result: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_finite(result), indent=1))


def _finite(x):
    """JSON has no infinity: refused pairs' errors are written as null."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, np.floating | np.integer | np.bool_):
        return _finite(x.item())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


if __name__ == "__main__":
    main()
