"""Which robot primitive pairs the self-collision check may skip, and the evidence for it.

Two rules, nothing else:
1. Kinematic neighbours are skipped: primitives on the same body, on bodies joined by one joint (parent and
   child), or on sibling bodies (the two fingers, whose gap the gripper itself controls). Their shapes overlap at
   the joint by construction.
2. A pair is skipped when its padded shapes provably cannot touch: its certified lower bound on the distance
   over every configuration (all joint ranges and the gripper stroke) exceeds that. The bound comes from branch
   and bound over the joints between the two shapes: moving joint k by dq moves the far shape by at most
   L_k |dq| (L_k: the link lengths from joint k to the shape plus the shape's reach; 1 for a finger slide), so
   a box of configurations whose centre is at distance d keeps every configuration above
   d - sum_k L_k * half-width_k. The box with the lowest bound is split along its widest L-weighted side until
   that slack is below CERTIFY_TOLERANCE_M (or CERTIFY_MAX_BOXES were made); the lowest bound of all boxes is a
   lower bound everywhere. Random sampling (SAMPLES configurations, joints pinned to a limit in 20 % of them)
   runs first: it finds the pairs that do touch, which are always checked, and a sampled minimum is kept beside
   each bound as a cross-check. Both live in self_collision_distances.yaml; regenerate with
   `python -m safety.self_collision` whenever the robot description changes (a test compares the file against
   the description's primitive names).
"""

from __future__ import annotations

import argparse
import heapq
import math
from itertools import combinations
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from drivers.files import load_yaml
from safety.backend_coal import add_primitive
from safety.geometry import Primitive, robot_primitives
from safety.robot_model import RobotModel

DISTANCES_FILE = Path(__file__).with_name("self_collision_distances.yaml")
SAMPLES = 300_000
CERTIFY_TOLERANCE_M = 0.005
CERTIFY_MAX_BOXES = 300_000


def _body(robot: RobotModel, prim: Primitive) -> int:
    return robot.model.frames[robot.model.getFrameId(prim.link)].parentJoint


def neighbours(robot: RobotModel, a: Primitive, b: Primitive) -> bool:
    """Same body, parent/child bodies, or sibling bodies (rule 1)."""
    ja, jb = _body(robot, a), _body(robot, b)
    parents = robot.model.parents
    return ja == jb or parents[ja] == jb or parents[jb] == ja or parents[ja] == parents[jb]


def candidate_pairs(robot: RobotModel, prims: list[Primitive]) -> list[tuple[int, int]]:
    return [(i, j) for i, j in combinations(range(len(prims)), 2) if not neighbours(robot, prims[i], prims[j])]


def load_certified_distances(path: Path = DISTANCES_FILE) -> dict[tuple[str, str], float | None]:
    """Certified lower bound per candidate pair (None: the pair can touch, or was not certified)."""
    doc = load_yaml(path, "certified distances")
    return {(row[0], row[1]): (None if row[3] is None else float(row[3])) for row in doc["pairs"]}


def padding_reach(prim: Primitive, padding_m: float) -> float:
    """How far the padded shape reaches beyond the shape: a box grown on each face reaches sqrt(3) x padding at
    its corners, a cylinder sqrt(2) x at its rims, a capsule or sphere exactly the padding."""
    return padding_m * {"box": math.sqrt(3.0), "cylinder": math.sqrt(2.0)}.get(prim.kind, 1.0)


def checked_self_pairs(robot: RobotModel, prims: list[Primitive], padding_m: float) -> list[tuple[int, int]]:
    """Index pairs (into prims) that the self-collision check must test at this padding: all but those whose
    certified distance exceeds what the padding adds to both shapes. A pair missing from the distances file
    (description changed) or without a certified bound is always tested."""
    bounds = load_certified_distances()
    out = []
    for i, j in candidate_pairs(robot, prims):
        d = bounds.get((prims[i].name, prims[j].name), bounds.get((prims[j].name, prims[i].name)))
        if d is None or d <= padding_reach(prims[i], padding_m) + padding_reach(prims[j], padding_m):
            out.append((i, j))
    return out


def certified_min_distance(
    robot: RobotModel,
    a: Primitive,
    b: Primitive,
    tolerance_m: float = CERTIFY_TOLERANCE_M,
    max_boxes: int = CERTIFY_MAX_BOXES,
) -> float:
    """A lower bound on the unpadded distance between two robot shapes over every configuration (rule 2)."""
    m = robot.model
    gmodel = pin.GeometryModel()
    ia, ib = add_primitive(gmodel, robot, a), add_primitive(gmodel, robot, b)
    gmodel.addCollisionPair(pin.CollisionPair(ia, ib))
    gdata, data = gmodel.createData(), m.createData()
    ends = {ia: gmodel.geometryObjects[ia].parentJoint, ib: gmodel.geometryObjects[ib].parentJoint}
    supports = {g: set(m.supports[j]) for g, j in ends.items()}
    joints = sorted((supports[ia] ^ supports[ib]) - {0})  # the joints that move one shape relative to the other
    lo, hi, lipschitz = [], [], []
    gripper = robot.spec.gripper
    for k in joints:
        g = ib if k in supports[ib] else ia
        if m.joints[k].nv == 1 and m.joints[k].shortname().startswith("JointModelP"):  # a finger slide
            lo.append(gripper.min_width_m / 2)
            hi.append(gripper.max_width_m / 2)
            lipschitz.append(1.0)
            continue
        qk = m.idx_qs[k]
        lower = float(m.lowerPositionLimit[qk])
        lo.append(lower)
        hi.append(min(float(m.upperPositionLimit[qk]), lower + 2 * math.pi))  # a turn repeats every 2 pi
        below = [j for j in m.supports[ends[g]] if j > k and k in m.supports[j]]
        arm = sum(float(np.linalg.norm(m.jointPlacements[j].translation)) for j in below)
        reach = float(np.linalg.norm(gmodel.geometryObjects[g].placement.translation))
        lipschitz.append(arm + reach + (a if g == ia else b).bounding_radius())
    L = np.array(lipschitz)
    index = [m.idx_qs[k] for k in joints]
    q = pin.neutral(m)

    def bound(box_lo: np.ndarray, box_hi: np.ndarray) -> float:
        q[index] = (box_lo + box_hi) / 2
        pin.updateGeometryPlacements(m, data, gmodel, gdata, q)
        return pin.computeDistance(gmodel, gdata, 0).min_distance - float(L @ (box_hi - box_lo)) / 2

    start_lo, start_hi = np.array(lo), np.array(hi)
    boxes = [(bound(start_lo, start_hi), 0, start_lo, start_hi)]
    made = 1
    while True:
        lowest, _, box_lo, box_hi = heapq.heappop(boxes)
        width = L * (box_hi - box_lo)
        if width.sum() / 2 <= tolerance_m or made >= max_boxes:
            return float(lowest)  # every other box's bound is at least this
        k = int(np.argmax(width))
        mid = (box_lo[k] + box_hi[k]) / 2
        left_hi, right_lo = box_hi.copy(), box_lo.copy()
        left_hi[k] = right_lo[k] = mid
        for half_lo, half_hi in ((box_lo, left_hi), (right_lo, box_hi)):
            heapq.heappush(boxes, (bound(half_lo, half_hi), made, half_lo, half_hi))
            made += 1


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
    parser = argparse.ArgumentParser(description="Sample and certify the closest approach of every non-neighbour pair.")
    parser.add_argument("--samples", type=int, default=SAMPLES)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    robot = RobotModel()
    by_name = {p.name: p for p in robot_primitives(robot.spec)}
    minima = measure_min_distances(robot, args.samples, args.seed)
    rows = []
    for (a, b), sampled in sorted(minima.items(), key=lambda kv: kv[1]):
        certified = certified_min_distance(robot, by_name[a], by_name[b]) if sampled > 0 else None
        rows.append([a, b, round(sampled, 5), None if certified is None else math.floor(certified * 1e5) / 1e5])
        if certified is not None:
            print(f"{a} / {b}: sampled {sampled:.4f} m, certified >= {certified:.4f} m")
    doc = {
        "method": f"[a, b, min unpadded distance over {args.samples} random configurations (seed {args.seed}), "
        "certified lower bound over all configurations or null when the pair can touch]; see "
        "safety/self_collision.py",
        "samples": args.samples,
        "pairs": rows,
    }
    DISTANCES_FILE.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))
    print(f"wrote {DISTANCES_FILE} ({len(rows)} pairs)")


if __name__ == "__main__":
    main()
