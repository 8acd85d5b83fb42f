"""Hinged parts (a lid, a door): the hinge recovered from the part's motion, and the arc push that turns it.

A hinged part can only turn about a fixed line, so its grounded motion (x_goal = T x_init, base frame) must be a
screw with no slide: the rotation's axis is the hinge direction, the least-squares solution of (I - R) p = t is
a point on it, and t's component along the axis is a slide the hinge cannot make. The part is modelled as a thin
plate containing the hinge line (a lid): the seen points give its direction away from the hinge, its extent and
the plate's offset. The closed fingers lie along the plate, pointing toward the hinge with the closing axis along
it, so their broad side presses the face that faces against the motion, near the free edge. They come to it
from beyond the free edge, slanted hinge_approach_deg in front of the face, so a part that has leaned further
toward them since the capture is pushed on its way rather than landed on (straight along the push would put
the pre-contact pose of a lid leaning toward the robot low and close to the arm's base, where it hardly
reaches). They keep that orientation and follow the contact point's arc about the hinge
to the goal angle, via poses at most hinge_step_deg apart. The last ends the fingers as near the part's face at the
goal as the scene's clearance allows (END_GAP_MIN_M up to hinge_end_max_gap_m): a stiff hinge holds a lid where
the fingers leave it, and the standoff kept on the way left small lids 12-19 deg open; what the part closes on
keeps them off a goal turned too far (an edited image's lid is shut a few degrees past its rim). Relative
to the turning plate the fingers turn away from it, so the standoff kept from the face at the fingers' nearest
corner is kept by the whole fingers (the hand, further back, is beyond the free edge of a part pushed near
that edge).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.contact.sampling import Candidate, frame
from pipeline.contact.types import ContactConfig
from safety.geometry import turn_about

MIN_EXTENT_M = 0.02  # a part shorter than this from its hinge has no free edge to push near
LATERAL = 0.15  # off-centre contacts this fraction of the part's width along the hinge from its middle
# the end pose's gaps off the seen face tried, in steps from the least: the pushed face is the unseen one, a
# plate's thickness (a lid's, up to a centimetre) beyond, and the fingers never press into the part
END_GAP_MIN_M, END_GAP_STEP_M = 0.012, 0.003


class HingeError(ValueError):
    """The motion is not a turn about a fixed hinge (says how far off it is)."""


@dataclass(frozen=True)
class Hinge:
    """A turn by angle_rad (right hand, > 0) about the line through point with unit direction axis, base frame."""

    axis: np.ndarray
    point: np.ndarray
    angle_rad: float

    def turn(self, angle_rad: float) -> np.ndarray:
        """T_base (4x4) of the turn by angle_rad about the hinge line."""
        return turn_about(self.point, self.axis, angle_rad)


def hinge_from_motion(T_base_motion: np.ndarray, max_slide_m: float, min_turn_deg: float) -> Hinge:
    """The hinge of a rigid motion by screw decomposition; HingeError if it slides or hardly turns."""
    T = np.asarray(T_base_motion, dtype=np.float64)
    rotvec = Rotation.from_matrix(T[:3, :3]).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    if math.degrees(angle) < min_turn_deg:
        raise HingeError(
            f"motion turns {math.degrees(angle):.1f} deg, below the {min_turn_deg:.0f} deg of a hinge push"
        )
    axis = rotvec / angle
    t = T[:3, 3]
    slide = float(axis @ t)
    if abs(slide) > max_slide_m:
        raise HingeError(
            f"motion slides {slide * 1000:.0f} mm along its rotation axis (a hinge allows {max_slide_m * 1000:.0f})"
        )
    # (I - R) is singular along the axis; the least-squares point is the line's point closest to the base origin
    point = np.linalg.lstsq(np.eye(3) - T[:3, :3], t - slide * axis, rcond=None)[0]
    return Hinge(axis, point, angle)


def arc_candidates(
    points: np.ndarray,
    hinge: Hinge,
    cfg: ContactConfig,
    fingers_tcp: np.ndarray,
    clear: Callable[[np.ndarray], bool] = lambda T: True,
) -> tuple[list[Candidate], dict[str, int]]:
    """Arc pushes on a plate hinged along `hinge`: contact near the free edge, laterally centred and off-centre.

    points: the part's cloud (N, 3), base frame. fingers_tcp: the closed fingers' box corners (K, 3), TCP frame:
    the nearest stays cfg.push_standoff_m from the pushed face along the arc, and ends at the least gap whose TCP
    pose `clear` accepts (the largest when none is). The seen face is taken as the pushed one: when the camera
    sees the other face, the standoff spans the plate's thickness.
    """
    rel = points - hinge.point
    along = rel @ hinge.axis
    radial = rel - np.outer(along, hinge.axis)
    u = np.linalg.svd(radial, full_matrices=False)[2][0]  # the plate's direction away from the hinge line
    u = u if (radial @ u).mean() > 0 else -u
    v = np.cross(hinge.axis, u)  # how the plate's points start to move
    extent = float(np.percentile(radial @ u, 98))
    if extent < MIN_EXTENT_M:
        return [], {f"part reaches only {extent * 1000:.0f} mm from the hinge": 1}
    face = float(np.percentile(radial @ v, 5))  # the seen points furthest against the motion
    lo, hi = np.percentile(along, (5, 95))
    # the gripper is symmetric about its approach axis: of the two closing-axis signs, the one with the TCP x axis
    # pointing away from the base, as in the arm's home posture, which keeps the wrist from turning half round
    away = np.array([*(hinge.point + extent * u)[:2], 0.0])
    R_tcp = frame(hinge.axis, -u, np.zeros(3))[:3, :3]
    R_tcp = R_tcp if R_tcp[:, 0] @ away >= 0 else R_tcp @ np.diag([-1.0, -1.0, 1.0])
    slant = math.radians(cfg.hinge_approach_deg)
    back_off = math.cos(slant) * u - math.sin(slant) * v
    steps = max(1, math.ceil(math.degrees(hinge.angle_rad) / cfg.hinge_step_deg - 1e-6))

    def pose(contact: np.ndarray, angle_rad: float, gap: float) -> np.ndarray:
        """The TCP pose with the fingers' nearest corner `gap` off the face turned by angle_rad at `contact`."""
        turn = hinge.turn(angle_rad)
        into = turn[:3, :3] @ v  # the pushed face's inward normal, turned with the part
        reach = float(np.max(fingers_tcp @ (R_tcp.T @ into)))
        T = np.eye(4)
        T[:3, :3] = R_tcp
        T[:3, 3] = turn[:3, :3] @ contact + turn[:3, 3] - (gap + reach) * into
        return T

    gaps = np.arange(END_GAP_MIN_M, cfg.hinge_end_max_gap_m + 1e-9, END_GAP_STEP_M)
    out = []
    for lateral in (0.0, -LATERAL, LATERAL):
        contact = hinge.point + cfg.hinge_contact_fraction * extent * u + face * v
        contact = contact + (0.5 * (lo + hi) + lateral * (hi - lo)) * hinge.axis
        poses = [pose(contact, k * hinge.angle_rad / steps, cfg.push_standoff_m) for k in range(steps)]
        ends = [pose(contact, hinge.angle_rad, gap) for gap in gaps]
        poses.append(next((T for T in ends if clear(T)), ends[-1]))
        centred = 1.0 - abs(lateral)
        down = float(np.clip(-R_tcp[2, 2], 0.0, 1.0))
        out.append(Candidate("hinge", poses[0], 0.0, 1.0, down, centred, tuple(poses[1:-1]), poses[-1], back_off))
    return out, {}
