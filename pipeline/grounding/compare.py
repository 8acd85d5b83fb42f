"""Verification's arithmetic: an achieved motion compared with the goal's, and the symmetries no image can show.

Both motions are measured the same way (grounding's registration, achieved.py) and compared where it matters:
the object's centre, moved by each. The rotation difference is split, in the base frame, into tilt (how far the
object's vertical axis is off) and twist (turn about the vertical), and each is judged only when the goal itself
asks for that kind of rotation (at least INTENDED_DEG): the registration of a symmetric object (a cube, a
cylinder) is free to pick any of its symmetric poses, so an unasked rotation is reported, never judged. A body of
revolution (an upright can, a bottle) shows no turn about its own axis, so that turn is taken out first and its
position is compared on the axis (the centroid of the seen side swings with the invisible turn); one whose ends
look alike (a can: one radius all along) shows no half turn end for end either (a can stood up on its other end
is stood up), so the smaller of the two errors counts; a ball shows no turn at all and is compared at its
centre. A box shows none of the turns that carry it onto itself (its half turns about its face axes, and the
quarter turns that swap sides of one length: seen_symmetry.box_turns, the simulator truth's own rule): the
smallest error over them counts, compared at the box's middle; where its faces are too few or too small to tell
(a small cube seen from afar), a box standing on a square footprint (square_footprint_axis) hides its quarter turns
about the vertical, compared at its seen centre. All are recognised from the initial points; a
print is not read (the simulator's truth judges shapes alone, and a print's turn judged on a uniform object whose
shading reads as a print would be a false failure).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from pipeline.contact.symmetry import TOLERANCE_REL, revolution_axis

INTENDED_DEG = 10.0
SAME_SIDE_M = 0.005  # a box's sides this close are one length: a turn swapping them does not show
RECTANGLE_FILL = 0.9  # a box's footprint fills its smallest rectangle; a disc fills pi/4 of it


def rotation_deg(R: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(R).magnitude()))


def twist_tilt_deg(R_base: np.ndarray) -> tuple[float, float]:
    """(turn about the base z axis, tilt of the z axis) of a rotation in the base frame, degrees."""
    _, _, z, w = Rotation.from_matrix(R_base).as_quat()
    twist = abs(math.degrees(2 * math.atan2(z, w)))
    twist = 360.0 - twist if twist > 180.0 else twist
    tilt = math.degrees(math.acos(float(np.clip(R_base[2, 2], -1.0, 1.0))))
    return twist, tilt


@dataclass(frozen=True)
class Symmetry:
    """What the seen points say no registration can see: turns about `axis` (unit, camera frame) of a body of
    revolution, the `turns` of a box onto itself, or any turn of a ball (neither). `centre` (camera frame, on the
    axis, the ball's or the box's middle) is where positions are compared, since the seen side's centroid swings
    with the unseen turn."""

    centre: np.ndarray
    axis: np.ndarray | None
    ends_alike: bool = False  # a body of revolution that looks the same turned end for end (a can)
    turns: np.ndarray | None = None  # a box: (K, 3, 3) camera-frame turns about `centre`, the identity among them

    @property
    def ball(self) -> bool:
        return self.axis is None and self.turns is None

    @property
    def name(self) -> str:
        if self.ball:
            return "ball"
        if self.axis is None:
            return "box"
        return "revolution_ends_alike" if self.ends_alike else "revolution"


def hidden_turns_out(R: np.ndarray, symmetry: Symmetry | None) -> np.ndarray:
    """A rotation R acting on the object as first seen, with the turns `symmetry` hides taken out: the swing of a
    body of revolution (the smaller of it and its end-for-end twin's when its ends look alike), the least of
    R's box twins S^T R, nothing of a ball's."""
    if symmetry is None:
        return R
    if symmetry.ball:
        return np.eye(3)
    if symmetry.axis is None:
        return min((S.T @ R for S in symmetry.turns), key=rotation_deg)
    seen_alike = [R, R @ half_turn_across(symmetry.axis)] if symmetry.ends_alike else [R]
    return min((without_turn_about(A, symmetry.axis) for A in seen_alike), key=rotation_deg)


def object_symmetry(points_camera: np.ndarray) -> Symmetry | None:
    """The symmetry of the object whose seen points (N, 3) are given, or None (a box, a pan: every turn shows)."""
    axis = revolution_axis(points_camera)
    if axis is None:
        return None
    P = np.asarray(points_camera, dtype=np.float64)  # a ball: on one sphere, |x|^2 = 2 c.x + k
    centre = np.linalg.lstsq(np.column_stack([2 * P, np.ones(len(P))]), (P**2).sum(axis=1), rcond=None)[0][:3]
    radius = np.linalg.norm(P - centre, axis=1)
    off = float(np.median(np.abs(radius - np.median(radius))))
    if off <= TOLERANCE_REL * float(np.linalg.norm(np.ptp(P, axis=0))):
        return Symmetry(centre, None)
    return Symmetry(axis.point, axis.direction, axis.ends_alike)


def square_footprint_axis(points_camera: np.ndarray, up_camera: np.ndarray) -> np.ndarray | None:
    """The vertical (camera frame) when the object is a box standing on a square footprint, so that turned a
    quarter about the vertical it shows the same outline; None otherwise. points_camera (N, 3): its seen points;
    up_camera: the table's normal. Its print is not read (a box whose texture shows the quarter turn counts as
    square too, as it does for the simulator's truth); the seen points' rectangle is off by up to 5 mm a side."""
    from cv2 import minAreaRect

    P = np.asarray(points_camera, dtype=np.float64)
    if len(P) < 50:
        return None
    up = up_camera / np.linalg.norm(up_camera)
    e1 = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    flat = np.column_stack([P @ e1, P @ np.cross(up, e1)]).astype(np.float32)
    (_, _), (a, b), _ = minAreaRect(flat)
    if a * b <= 0 or float(ConvexHull(flat).volume) < RECTANGLE_FILL * a * b or abs(a - b) > SAME_SIDE_M:
        return None
    return up


def quarter_turn(axis: np.ndarray, k: int) -> np.ndarray:
    return Rotation.from_rotvec(k * np.pi / 2 * axis).as_matrix()


def without_turn_about(R: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """R with its turn about `axis` taken out (the swing of a swing-twist split)."""
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    along = (np.array([x, y, z]) @ axis) * axis
    twist = np.array([*along, w])
    norm = np.linalg.norm(twist)
    twist = twist / norm if norm > 1e-12 else np.array([0.0, 0.0, 0.0, 1.0])
    return (Rotation.from_quat([x, y, z, w]) * Rotation.from_quat(twist).inv()).as_matrix()


def half_turn_across(axis: np.ndarray) -> np.ndarray:
    """A half turn about a line square to `axis` (which one does not matter once turns about `axis` are out)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    across = np.cross(axis, helper)
    return Rotation.from_rotvec(np.pi * across / np.linalg.norm(across)).as_matrix()


def spins_about(axis: np.ndarray, step_deg: float) -> np.ndarray:
    """(K, 3, 3) the turns about the unit `axis` by 0, step_deg, 2 step_deg, ... short of a whole turn."""
    return Rotation.from_rotvec(np.radians(np.arange(0.0, 360.0, step_deg))[:, None] * axis).as_matrix()


def tied_run(tied: np.ndarray, start: int) -> tuple[int, int]:
    """(lo, hi): the run of True in `tied` (K,: one per spin, round the circle) holding index `start`, as indices
    lo <= start <= hi that may reach past either end (taken modulo K); at most the whole circle."""
    n, lo, hi = len(tied), start, start
    while tied[(lo - 1) % n] and hi - lo < n - 1:
        lo -= 1
    while tied[(hi + 1) % n] and hi - lo < n - 1:
        hi += 1
    return lo, hi


def sphere_directions(count: int) -> np.ndarray:
    """(count, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    azimuth = np.pi * (1.0 + 5**0.5) * k
    ring = np.sqrt(1.0 - z**2)
    return np.stack([ring * np.cos(azimuth), ring * np.sin(azimuth), z], axis=1)


def object_centre(points_camera: np.ndarray) -> np.ndarray:
    """Centre of the visible object points (N, 3) in the camera frame, robust to stray edge pixels."""
    return np.median(points_camera, axis=0)


class Comparison(BaseModel):
    """The verdict on an achieved motion, with every number it was judged by (errors, the goal's own turns, which
    turns were judged, the tolerances)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    ok: bool
    reason: str
    position_error_m: float
    rotation_error_deg: float
    goal_translation_m: float
    achieved_translation_m: float
    goal_twist_deg: float
    goal_tilt_deg: float
    twist_error_deg: float
    tilt_error_deg: float
    twist_judged: bool
    tilt_judged: bool
    symmetry: Literal["none", "ball", "revolution", "revolution_ends_alike", "box"]
    position_tol_m: float
    rotation_tol_deg: float


def compare(
    *,
    goal_R: np.ndarray,
    goal_t: np.ndarray,
    achieved_R: np.ndarray,
    achieved_t: np.ndarray,
    centre_camera: np.ndarray,
    R_base_camera: np.ndarray,
    position_tol_m: float,
    rotation_tol_deg: float,
    symmetry: Symmetry | None = None,
) -> Comparison:
    """Verdict from the goal and achieved motions (x' = R x + t, camera frame) of an object centred at centre;
    with a symmetry, positions are compared at its centre and turns it hides are not judged."""
    if symmetry is not None:
        centre_camera = symmetry.centre
    p_goal = goal_R @ centre_camera + goal_t
    p_achieved = achieved_R @ centre_camera + achieved_t
    position_error = float(np.linalg.norm(p_goal - p_achieved))
    to_base = lambda R: R_base_camera @ R @ R_base_camera.T  # noqa: E731
    goal_twist, goal_tilt = twist_tilt_deg(to_base(goal_R))
    # acts on the object as first seen, where the symmetry was found; goal_R S for a turn S it hides is the goal too
    R_error = hidden_turns_out(goal_R.T @ achieved_R, symmetry)
    twist_error, tilt_error = twist_tilt_deg(to_base(R_error))
    turns_seen = symmetry is None or not symmetry.ball  # no turn of a ball shows
    judge_twist, judge_tilt = turns_seen and goal_twist >= INTENDED_DEG, turns_seen and goal_tilt >= INTENDED_DEG
    problems = []
    if position_error > position_tol_m:
        problems.append(
            f"object centre {position_error * 1000:.0f} mm from the goal (tolerance {position_tol_m * 1000:.0f})"
        )
    if judge_tilt and tilt_error > rotation_tol_deg:
        problems.append(f"object tilted {tilt_error:.1f} deg off the goal (tolerance {rotation_tol_deg:.0f})")
    if judge_twist and twist_error > rotation_tol_deg:
        problems.append(f"object turned {twist_error:.1f} deg off the goal (tolerance {rotation_tol_deg:.0f})")
    reason = "; ".join(problems) or (
        f"goal reached: centre within {position_error * 1000:.0f} mm"
        + (f", tilt within {tilt_error:.1f} deg" if judge_tilt else "")
        + (f", turn within {twist_error:.1f} deg" if judge_twist else "")
    )
    return Comparison(
        ok=not problems,
        reason=reason,
        position_error_m=position_error,
        rotation_error_deg=rotation_deg(goal_R.T @ achieved_R),
        goal_translation_m=float(np.linalg.norm(p_goal - centre_camera)),
        achieved_translation_m=float(np.linalg.norm(p_achieved - centre_camera)),
        goal_twist_deg=goal_twist,
        goal_tilt_deg=goal_tilt,
        twist_error_deg=twist_error,
        tilt_error_deg=tilt_error,
        twist_judged=judge_twist,
        tilt_judged=judge_tilt,
        symmetry="none" if symmetry is None else symmetry.name,
        position_tol_m=position_tol_m,
        rotation_tol_deg=rotation_tol_deg,
    )


def turns_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M, 3, 3) the least rotations taking unit `a` (3,) onto each unit row of `b` (M, 3) (a half turn square to `a`
    where they are opposite)."""
    c = b @ a
    v = np.cross(a, b)
    V = np.zeros((len(b), 3, 3))
    V[:, 0, 1], V[:, 0, 2], V[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    V[:, 1, 0], V[:, 2, 0], V[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    R = np.eye(3) + V + V @ V / np.maximum(1.0 + c, 1e-9)[:, None, None]
    opposite = c < -1.0 + 1e-9
    R[opposite] = half_turn_across(a)
    return R
