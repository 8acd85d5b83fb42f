"""Stage 1 offline chain on seeded sim scenes: how often a goal is accepted, whether grounding recovers the motion
the goal image encodes (within 1 cm and 5 deg), and seconds per stage.

Four scenes (the repository's tabletop, close_lid and bottle_standup, and a mix of colours and a bowl written to a
temporary folder), each with a different seeded placement per case and an instruction cycled from a list covering
every action of the grammar: every relation of place, rotations, pushes, stand-up and closing a hinged lid. The
intended motion is the rigid motion the offline editor applied (for "close", the lid's turn about its hinge); the
grounded motion comes from pipeline.grounding with the offline features. Translation error is measured at the
target's centroid; for bodies symmetric about the vertical (cylinders, bowls, a stood-up bottle) the unobservable
turn about the vertical is not counted in the rotation error (the strict figure is kept per case), and the
translation error is measured on the axis (the body's true centre, from the simulator) instead, since the centroid
of the visible surface swings with that unobservable turn. Figures are
also given per action.

    python bench/reasoning.py [--quick] --out RESULT.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

# bench/safety.py would shadow the safety package: drop this folder from the import path
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from drivers.sim import SimCamera, SimWorld  # noqa: E402
from pipeline.config import PipelineConfig  # noqa: E402
from pipeline.grounding.compare import rotation_deg, without_turn_about  # noqa: E402
from pipeline.grounding.ground import ground  # noqa: E402
from pipeline.grounding.types import GroundingInput  # noqa: E402
from pipeline.perception.features import make_feature_extractor  # noqa: E402
from pipeline.reasoning.factory import build_reasoner  # noqa: E402
from pipeline.reasoning.instruction import parse_instruction  # noqa: E402
from pipeline.reasoning.types import ReasoningError  # noqa: E402
from runtime.config import load_profile  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
TARGETS = {"accepted_fraction": 0.9, "grounded_within_tolerance_fraction": 0.9, "reasoning_s_median": 2.0}
TOLERANCE = {"translation_m": 0.01, "rotation_deg": 5.0}
# turning these about the vertical changes nothing visible: that part of the rotation error is not counted
# (bottles are only stood up here, so their axis of symmetry ends vertical)
SYMMETRIC_SHAPES = ("cylinder", "can", "bowl", "plate", "ball", "sphere", "bottle")
SCENES = ("tabletop", "bench_mixed", "close_lid", "bottle_standup")
MIXED_SCENE = {
    "name": "bench_mixed",
    "description": "Reasoning benchmark: five colours and a bowl.",
    "objects": [
        {
            "name": "yellow_block",
            "kind": "box",
            "size_m": [0.045, 0.045, 0.045],
            "color": "yellow",
            "xy_m": [0.42, -0.15],
        },
        {
            "name": "purple_cylinder",
            "kind": "cylinder",
            "radius_m": 0.025,
            "height_m": 0.09,
            "color": "purple",
            "xy_m": [0.40, 0.12],
        },
        {"name": "cyan_bowl", "kind": "bowl", "radius_m": 0.07, "height_m": 0.05, "color": "cyan", "xy_m": [0.58, 0.0]},
        {"name": "red_block", "kind": "box", "size_m": [0.05, 0.04, 0.04], "color": "red", "xy_m": [0.62, -0.22]},
    ],
    "randomise": {"xy_jitter_m": 0.03, "yaw_jitter_deg": 25},
}
INSTRUCTIONS = {
    "tabletop": [
        "put the red block on the white plate",
        "move the blue block to the left of the green cylinder",
        "place the green cylinder behind the blue block",
        "put the red block in front of the blue block",
        "move the red block next to the green cylinder",
        "rotate the blue block by 40 degrees",
        "push the green cylinder right by 8 cm",
        "put the blue block on the white plate",
        "place the red block right of the blue block",
        "turn the red block 30 degrees clockwise",
    ],
    "bench_mixed": [
        "put the yellow block in the cyan bowl",
        "move the purple cylinder left of the red block",
        "place the red block in front of the yellow block",
        "put the yellow block behind the purple cylinder",
        "push the red block left by 10 cm",
        "rotate the yellow block by 25 degrees",
        "move the purple cylinder next to the cyan bowl",
        "put the red block in the cyan bowl",
        "place the yellow block to the right of the purple cylinder",
        "push the purple cylinder forward by 6 cm",
    ],
    "close_lid": [
        "close the blue box",
        "push the orange block left by 6 cm",
        "close the blue box",
        "rotate the orange block by 30 degrees",
        "close the blue box",
        "move the orange block in front of the blue box",
    ],
    "bottle_standup": [
        "stand the green bottle up",
        "push the red block left by 8 cm",
        "stand up the green bottle",
        "rotate the red block by 45 degrees",
    ],
}


def capture(scenes_dir: Path, scene: str, seed: int):
    """(frame, [(object's mask, its true centre in the camera frame)]) of one seeded scene."""
    profile = load_profile(REPO / "configs" / "sim.yaml", {"sim": {"realtime": False, "scene": scene, "seed": seed}})
    profile = profile.model_copy(update={"sim": profile.sim.model_copy(update={"scenes_dir": scenes_dir})})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=seed) as camera:
        frame = camera.read().with_extrinsics(world.T_world_camera)
        masks = camera.object_masks()
    m, d = world.model, world.data
    T_camera_base = np.linalg.inv(frame.T_base_camera)
    truth = []
    for name, mask in masks.items():
        geoms = np.flatnonzero(m.body_rootid[m.geom_bodyid] == m.body(name).id)
        truth.append((mask, T_camera_base[:3, :3] @ d.geom_xpos[geoms].mean(axis=0) + T_camera_base[:3, 3]))
    return frame, truth


def motion_error(
    T_intended: np.ndarray, R: np.ndarray, t: np.ndarray, centroid: np.ndarray, up: np.ndarray | None
) -> tuple[float, float]:
    """Centroid displacement error [m] and rotation error [deg] (ignoring turns about `up` when given)."""
    moved_intended = T_intended[:3, :3] @ centroid + T_intended[:3, 3]
    moved_grounded = R @ centroid + t
    R_err = R @ T_intended[:3, :3].T
    angle = rotation_deg(without_turn_about(R_err, up) if up is not None else R_err)
    return float(np.linalg.norm(moved_grounded - moved_intended)), angle


def run_case(reasoner, features, frame, truth, instruction: str) -> dict:
    case: dict = {"instruction": instruction, "action": parse_instruction(instruction).action}
    t0 = time.perf_counter()
    try:
        goal = reasoner.run(frame, instruction)
    except ReasoningError as e:
        case.update(accepted=False, reasons=e.reasons, reasoning_s=time.perf_counter() - t0)
        return case
    case.update(accepted=goal.validated, reasoning_s=time.perf_counter() - t0, stages=goal.seconds)
    t0 = time.perf_counter()
    inp = GroundingInput.from_goal(frame, goal)
    motion = ground(inp, features)
    case["grounding_s"] = time.perf_counter() - t0
    case["grounded"] = motion.ok
    if not motion.ok:
        case["grounding_reason"] = motion.reason
        return case
    points = frame.intrinsics.unproject_depth_image(frame.depth)[goal.mask_init]
    centroid = points[np.isfinite(points).all(axis=1)].mean(axis=0)
    symmetric = any(word in goal.target for word in SYMMETRIC_SHAPES)
    up = frame.T_base_camera[:3, :3].T @ np.array([0.0, 0.0, 1.0]) if symmetric else None
    if symmetric:  # measure on the axis: the body's true centre (the object the target mask covers most)
        centroid = max(truth, key=lambda mask_centre: (mask_centre[0] & goal.mask_init).sum())[1]
    err_m, err_deg = motion_error(goal.T_goal_init_camera, motion.R, motion.t, centroid, up)
    _, strict_deg = motion_error(goal.T_goal_init_camera, motion.R, motion.t, centroid, None)
    case.update(translation_error_m=err_m, rotation_error_deg=err_deg, rotation_error_deg_strict=strict_deg)
    case.update(symmetric_about_vertical=symmetric, scale=motion.scale)
    case["within_tolerance"] = err_m <= TOLERANCE["translation_m"] and err_deg <= TOLERANCE["rotation_deg"]
    return case


def summarise(cases: list[dict]) -> dict:
    result = _figures(cases)
    actions = sorted({c["action"] for c in cases})
    result["per_action"] = {
        a: {k: _figures([c for c in cases if c["action"] == a])[k] for k in PER_ACTION} for a in actions
    }
    return result


PER_ACTION = ("cases", "accepted_fraction", "grounded_within_tolerance_fraction", "translation_error_m_median")


def _figures(cases: list[dict]) -> dict:
    accepted = [c for c in cases if c["accepted"]]
    within = [c for c in accepted if c.get("within_tolerance")]
    stages: dict[str, list[float]] = {}
    for c in accepted:
        for k, v in c["stages"].items():
            stages.setdefault(k, []).append(v)
        stages.setdefault("grounding", []).append(c["grounding_s"])
    errors_m = [c["translation_error_m"] for c in accepted if "translation_error_m" in c]
    errors_deg = [c["rotation_error_deg"] for c in accepted if "rotation_error_deg" in c]
    return {
        "cases": len(cases),
        "accepted_fraction": len(accepted) / len(cases),
        "grounded_within_tolerance_fraction": len(within) / max(len(accepted), 1),
        "grounding_refused": sum(1 for c in accepted if not c["grounded"]),
        "translation_error_m_median": float(np.median(errors_m)) if errors_m else None,
        "translation_error_m_p95": float(np.percentile(errors_m, 95)) if errors_m else None,
        "rotation_error_deg_median": float(np.median(errors_deg)) if errors_deg else None,
        "rotation_error_deg_p95": float(np.percentile(errors_deg, 95)) if errors_deg else None,
        "reasoning_s_median": float(np.median([c["reasoning_s"] for c in cases])),
        "stage_s_mean": {k: float(np.mean(v)) for k, v in stages.items()},
        "tolerance": TOLERANCE,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="8 scenes instead of 50")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    n = 8 if args.quick else 50
    reasoner = build_reasoner(PipelineConfig())
    features = make_feature_extractor("offline")
    cases = []
    with tempfile.TemporaryDirectory() as tmp:
        scenes_dir = Path(tmp)
        (scenes_dir / "bench_mixed.yaml").write_text(yaml.safe_dump(MIXED_SCENE))
        for name in SCENES[:1] + SCENES[2:]:
            (scenes_dir / f"{name}.yaml").write_text((REPO / "configs" / "scenes" / f"{name}.yaml").read_text())
        for i in range(n):
            scene = SCENES[i % len(SCENES)]
            instruction = INSTRUCTIONS[scene][(i // len(SCENES)) % len(INSTRUCTIONS[scene])]
            frame, truth = capture(scenes_dir, scene, seed=100 + i)
            case = run_case(reasoner, features, frame, truth, instruction)
            case.update(scene=scene, seed=100 + i)
            cases.append(case)
    result = summarise(cases)
    result["targets"] = TARGETS
    result["met"] = {
        "accepted_fraction": result["accepted_fraction"] >= TARGETS["accepted_fraction"],
        "grounded_within_tolerance_fraction": result["grounded_within_tolerance_fraction"]
        >= TARGETS["grounded_within_tolerance_fraction"],
        "reasoning_s_median": result["reasoning_s_median"] <= TARGETS["reasoning_s_median"],
    }
    result["case_results"] = cases
    args.out.write_text(json.dumps(result, indent=2, default=float))

    table = Table(title=f"Offline goal reasoning on {n} sim scenes")
    table.add_column("figure")
    table.add_column("value", justify="right")
    table.add_column("target", justify="right")
    for key in ("accepted_fraction", "grounded_within_tolerance_fraction", "reasoning_s_median"):
        table.add_row(key, f"{result[key]:.3f}", f"{TARGETS[key]} {'ok' if result['met'][key] else 'MISSED'}")
    for key in (
        "translation_error_m_median",
        "translation_error_m_p95",
        "rotation_error_deg_median",
        "rotation_error_deg_p95",
        "grounding_refused",
    ):
        value = result[key]
        table.add_row(key, "-" if value is None else f"{value:.4g}", "")
    for stage, s in result["stage_s_mean"].items():
        table.add_row(f"seconds: {stage}", f"{s:.3f}", "")
    Console().print(table)
    per_action = Table(title="Per action")
    for column in PER_ACTION:
        per_action.add_column(column)
    per_action.add_column("action", justify="left")
    for action, figures in result["per_action"].items():
        per_action.add_row(*("-" if figures[k] is None else f"{figures[k]:.3g}" for k in PER_ACTION), action)
    Console().print(per_action)
    for c in cases:
        if not c["accepted"] or not c.get("within_tolerance"):
            err_cm, err_deg = (
                c.get("translation_error_m", float("nan")) * 100,
                c.get("rotation_error_deg", float("nan")),
            )
            reason = c.get("reasons") or c.get("grounding_reason") or f"error {err_cm:.2f} cm, {err_deg:.2f} deg"
            Console().print(f"[yellow]{c['scene']} seed {c['seed']}: {c['instruction']}: {reason}")


if __name__ == "__main__":
    main()
