"""Which robot primitive pairs the self-collision check may skip, and the evidence for it.

Two rules, nothing else:
1. Kinematic neighbours are skipped: primitives on the same body, on bodies joined by one joint (parent and
   child), or on sibling bodies (the two fingers, whose gap the gripper itself controls). Their shapes overlap at
   the joint by construction.
2. A pair is skipped when it cannot come close: in SAMPLES random configurations over the full joint ranges and
   gripper stroke (uniform, with each joint pinned to a limit in 20 % of samples so the range corners are
   visited) its smallest unpadded distance stayed above 2 * padding + SAMPLING_MARGIN_M. The margin covers what
   sampling can miss between samples. The per-pair minima live in self_collision_distances.yaml; regenerate with
   `python -m safety.self_collision` whenever the robot description changes (a test compares the file against
   the description's primitive names).
"""

from __future__ import annotations

import argparse
from itertools import combinations
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from safety.backend_coal import add_primitive
from safety.geometry import Primitive, robot_primitives
from safety.robot_model import RobotModel

DISTANCES_FILE = Path(__file__).with_name("self_collision_distances.yaml")
SAMPLING_MARGIN_M = 0.02
SAMPLES = 300_000


def _body(robot: RobotModel, prim: Primitive) -> int:
    return robot.model.frames[robot.model.getFrameId(prim.link)].parentJoint


def neighbours(robot: RobotModel, a: Primitive, b: Primitive) -> bool:
    """Same body, parent/child bodies, or sibling bodies (rule 1)."""
    ja, jb = _body(robot, a), _body(robot, b)
    parents = robot.model.parents
    return ja == jb or parents[ja] == jb or parents[jb] == ja or parents[ja] == parents[jb]


def candidate_pairs(robot: RobotModel, prims: list[Primitive]) -> list[tuple[int, int]]:
    return [(i, j) for i, j in combinations(range(len(prims)), 2) if not neighbours(robot, prims[i], prims[j])]


def load_min_distances(path: Path = DISTANCES_FILE) -> dict[tuple[str, str], float]:
    with open(path) as f:
        doc = yaml.safe_load(f)
    return {(row[0], row[1]): float(row[2]) for row in doc["pairs"]}


def checked_self_pairs(robot: RobotModel, prims: list[Primitive], padding_m: float) -> list[tuple[int, int]]:
    """Index pairs (into prims) that the self-collision check must test at this padding. A pair missing from the
    distances file (description changed) is always tested."""
    minima = load_min_distances()
    threshold = 2 * padding_m + SAMPLING_MARGIN_M
    out = []
    for i, j in candidate_pairs(robot, prims):
        d = minima.get((prims[i].name, prims[j].name), minima.get((prims[j].name, prims[i].name)))
        if d is None or d <= threshold:
            out.append((i, j))
    return out


def sample_configurations(robot: RobotModel, n: int, rng: np.random.Generator) -> np.ndarray:
    """Full Pinocchio configurations: uniform arm angles, 20 % of joints pinned to a limit, random finger gap."""
    q = rng.uniform(robot.lower, robot.upper, size=(n, robot.dof))
    pin_mask = rng.random((n, robot.dof)) < 0.2
    q = np.where(pin_mask, np.where(rng.random((n, robot.dof)) < 0.5, robot.lower, robot.upper), q)
    g = robot.spec.gripper
    half_gap = rng.uniform(g.min_width_m, g.max_width_m, size=(n, 1)) / 2
    return np.hstack([q, half_gap, half_gap])


def measure_min_distances(robot: RobotModel, samples: int, seed: int) -> dict[tuple[str, str], float]:
    prims = robot_primitives(robot.spec)
    gmodel = pin.GeometryModel()
    for p in prims:
        add_primitive(gmodel, robot, p)
    pairs = candidate_pairs(robot, prims)
    for i, j in pairs:
        gmodel.addCollisionPair(pin.CollisionPair(i, j))
    gdata, data = gmodel.createData(), robot.model.createData()
    minima = np.full(len(pairs), np.inf)
    for qf in sample_configurations(robot, samples, np.random.default_rng(seed)):
        pin.computeDistances(robot.model, data, gmodel, gdata, qf)
        minima = np.minimum(minima, [r.min_distance for r in gdata.distanceResults])
    return {(prims[i].name, prims[j].name): float(d) for (i, j), d in zip(pairs, minima, strict=True)}


def main() -> None:
    parser = argparse.ArgumentParser(description="Measure the closest approach of every non-neighbour pair.")
    parser.add_argument("--samples", type=int, default=SAMPLES)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    minima = measure_min_distances(RobotModel(), args.samples, args.seed)
    doc = {
        "method": f"min unpadded distance over {args.samples} random configurations (seed {args.seed}); "
        "see safety/self_collision.py",
        "samples": args.samples,
        "pairs": [[a, b, round(d, 5)] for (a, b), d in sorted(minima.items(), key=lambda kv: kv[1])],
    }
    DISTANCES_FILE.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))
    print(f"wrote {DISTANCES_FILE} ({len(minima)} pairs)")


if __name__ == "__main__":
    main()
