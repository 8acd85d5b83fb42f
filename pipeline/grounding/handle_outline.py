"""A handled body's spin about its own axis, read from the goal mask's outline.

Where a mug's or a pan's handle points shows in the goal image mostly as where its outline reaches out beyond the
round body. handle.turn_by_handle reads it from the handle's points landing on the goal mask, which a segmenter's
mask grown a few pixels all round also grants a handle turned where the goal shows none: raycast mugs came out 6-108
deg off, a handle hidden behind the body scoring less than one laid along the grown mask. The outline fit
(outline_fit.py) takes out such a uniform growth, so a handle reaching out where the goal outline does not (or none
where it does) costs. The body's spins about its axis are tried, and the best taken only where it fits the outline
clearly better than the motion's own spin and lies along it nearly all round. A handle hidden behind the body, or
end for end on a body laid down, leaves runs of spins fitting alike: of those the run nearest the motion's is taken,
and its middle (the handle straight behind the body; the run's edge nearest the motion had left raycast mugs 56 deg
off).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.compare import spins_about
from pipeline.grounding.handle import HandledBody
from pipeline.grounding.outline_fit import GoalOutline, parabola_vertex
from pipeline.grounding.umeyama import Similarity

STEP_DEG = 5.0  # the spins about the body's axis tried
BETTER_BY_PX2 = 0.5  # the best spin's misfit must be this much under the motion's own (raycast mugs: 1-2 px^2 when
# the handle is on the wrong side, under 0.3 among spins that hide it)
TIED_PX2 = 0.1  # spins within this of the best fit the outline alike
MIN_ALONG = 0.95  # the best spin's hull share along the outline: less, and the outline is not this body's


def spun_to_outline(motion: Similarity, handled: HandledBody, whole: np.ndarray, outline: GoalOutline) -> Similarity:
    """`motion` after the body is spun about its axis (`handled`, as in the capture) so that the hull of its `whole`
    (N, 3: HandledBody.whole) lies along the goal outline; `motion` itself unless a spin fits clearly better."""
    spins = spins_about(handled.axis, STEP_DEG)
    fits = outline.fits(np.stack([motion.turned_first(g, handled.centre).apply(whole) for g in spins]))
    cost = fits.cost
    best = int(np.argmin(cost))
    if not cost[0] - cost[best] > BETTER_BY_PX2 or fits.along[best] < MIN_ALONG:
        return motion
    n = len(spins)
    steps = np.arange(n)
    away = np.minimum(steps, n - steps)  # steps from the motion's own spin, either way round
    tied = cost <= cost[best] + TIED_PX2
    pick = int(np.argmin(np.where(tied, away, n)))
    lo, hi = pick, pick  # the run of tied spins it lies in: a handle hidden behind the body ties over a sector
    while tied[(lo - 1) % n] and hi - lo < n - 1:
        lo -= 1
    while tied[(hi + 1) % n] and hi - lo < n - 1:
        hi += 1
    if hi > lo:  # the middle of the run: the handle straight behind, not at the edge of the sector that hides it
        angle = np.radians(STEP_DEG) * 0.5 * (lo + hi)
    else:
        angle = np.radians(STEP_DEG) * (pick + parabola_vertex(*cost[(pick + np.array([-1, 0, 1])) % n]))
    return motion.turned_first(Rotation.from_rotvec(angle * handled.axis).as_matrix(), handled.centre)
