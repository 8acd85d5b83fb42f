"""Where along the table a goal lies, read from the goal mask's outline.

A model's goal depth can put a large object centimetres off along the table (a dilated mask's edge bled onto the far
table pulls the goal cloud, and ICP with it, away from the camera): raycast pans slid or turned came out 12-46 mm
off with their rotation right, the goal image showing them 5-9 pixels from where the motion put them. A body whose
whole shape the capture gives (a box's corners, a body of revolution's seen slices spun round its axis, a handled
body's with its handle) is moved along the table, keeping its height above it (ray_rest.py set that), until its hull
lies on the goal outline (outline_fit.py): the image shift the fit finds, turned into a move in the table's plane
through the body's projection. Not moved where, so placed, the hull does not lie along the outline nearly all round
(MIN_ALONG: a hull that only partly fits is no evidence where it lies), the shift is within the hull's own error
(MIN_MOVE_PX) or the move is too large to be depth error (MAX_MOVE_REL).
"""

from __future__ import annotations

import numpy as np

from pipeline.contact.symmetry import basis_across
from pipeline.grounding.outline_fit import GoalOutline
from pipeline.grounding.umeyama import Similarity

MIN_ALONG = 0.95  # the hull's share within outline_fit.OFF_PX of the outline
# a hull drawn from seen points is itself a few pixels off (its bottom cut where it meets the support, a handle's
# unseen underside): a smaller shift is within what the outline tells, and a good goal depth places better (MuJoCo
# boxes 1 -> 3 mm; raycast pans right within 2 mm moved 4-7 mm by shifts of 2.1-2.6 px)
MIN_MOVE_PX = 3.0
MAX_MOVE_REL = 0.25  # of the object's size (as ICP may shift a hypothesis: select.MAX_ICP_SHIFT_REL)
ROUNDS = 2  # the move is linearised at the body's centre: a second round takes up what that leaves


def placed_on_outline(
    motion: Similarity, body: np.ndarray, centre: np.ndarray, up: np.ndarray, outline: GoalOutline, size: float
) -> Similarity:
    """`motion` moved in the plane of the table (normal `up`, camera frame) so that the hull of the `body`'s points
    (N, 3, as in the capture) lies on the goal outline; `centre` (3,): the body's, as in the capture. `motion` itself
    where the hull does not fit or the move exceeds MAX_MOVE_REL of `size`."""
    K, plane = outline.K, np.column_stack(basis_across(up))
    moved = motion
    for _ in range(ROUNDS):
        fits = outline.fits(moved.apply(body)[None])
        if not np.isfinite(fits.cost[0]):  # hidden nearly all round
            return motion
        if moved is motion and np.linalg.norm(fits.move_px[0]) < MIN_MOVE_PX:
            return motion
        x, y, z = moved.apply(centre[None])[0]
        image_of = np.array([[K.fx / z, 0.0, -K.fx * x / z**2], [0.0, K.fy / z, -K.fy * y / z**2]])  # d(u, v)/dX
        step = plane @ np.linalg.solve(image_of @ plane, fits.move_px[0])
        moved = Similarity(moved.scale, moved.R, moved.t + step)
    if np.linalg.norm(moved.t - motion.t) > MAX_MOVE_REL * size:
        return motion
    return moved if outline.fits(moved.apply(body)[None]).along[0] >= MIN_ALONG else motion
