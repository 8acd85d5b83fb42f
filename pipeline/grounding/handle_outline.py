"""A handled body's spin about its own axis, read from the goal mask's outline.

Where a mug's or a pan's handle points shows in the goal image mostly as where its outline reaches out beyond the
round body. handle.turn_by_handle reads it from the handle's points landing on the goal mask, which a segmenter's
mask grown a few pixels all round also grants a handle turned where the goal shows none: raycast mugs came out 6-108
deg off, a handle hidden behind the body scoring less than one laid along the grown mask. The outline fit
(outline_fit.py) takes out such a uniform growth, so a handle reaching out where the goal outline does not (or none
where it does) costs. The body's spins about its axis are tried, and the best taken only where it fits the outline
clearly better than the motion's own spin and lies along it nearly all round; short of that, the bottom of the dip
the motion's own spin lies in, a few steps away at most, is taken. A handle hidden behind the body, or
end for end on a body laid down, leaves runs of spins fitting alike: of those the run nearest the motion's is taken,
and its middle (the handle straight behind the body; the run's edge nearest the motion had left raycast mugs 56 deg
off).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.compare import spins_about, tied_run
from pipeline.grounding.handle import HandledBody
from pipeline.grounding.outline_fit import GoalOutline, parabola_vertex
from pipeline.grounding.umeyama import Similarity

STEP_DEG = 5.0  # the spins about the body's axis tried
BETTER_BY_PX2 = 0.5  # the best spin's misfit must be this much under the motion's own (raycast mugs: 1-2 px^2 when
# the handle is on the wrong side, under 0.3 among spins that hide it)
TIED_PX2 = 0.1  # spins within this of the best fit the outline alike
MIN_ALONG = 0.95  # the best spin's hull share along the outline: less, and the outline is not this body's
DIP_STEPS = 3  # a spin fitting better within this many steps of the motion's own is the bottom of the dip it lies in


def spun_to_outline(motion: Similarity, handled: HandledBody, whole: np.ndarray, outline: GoalOutline) -> Similarity:
    """`motion` after the body is spun about its axis (`handled`, as in the capture) so that the hull of its `whole`
    (N, 3: HandledBody.whole) lies along the goal outline; `motion` itself unless a spin fits clearly better."""
    spins = spins_about(handled.axis, STEP_DEG)
    fits = outline.fits(np.stack([motion.turned_first(g, handled.centre).apply(whole) for g in spins]))
    cost = fits.cost
    best = int(np.argmin(cost))
    if not cost[0] - cost[best] > BETTER_BY_PX2 or fits.along[best] < MIN_ALONG:
        return _dip_bottom(motion, handled, cost, fits.along)
    n = len(spins)
    steps = np.arange(n)
    away = np.minimum(steps, n - steps)  # steps from the motion's own spin, either way round
    tied = cost <= cost[best] + TIED_PX2
    pick = int(np.argmin(np.where(tied, away, n)))
    lo, hi = tied_run(tied, pick)  # a handle hidden behind the body ties over a sector
    # the middle of the run: the handle straight behind, not at the edge of the sector that hides it
    angle = np.radians(STEP_DEG) * 0.5 * (lo + hi) if hi > lo else _refined_angle(cost, pick)
    return motion.turned_first(Rotation.from_rotvec(angle * handled.axis).as_matrix(), handled.centre)


def _dip_bottom(motion: Similarity, handled: HandledBody, cost: np.ndarray, along: np.ndarray) -> Similarity:
    """`motion` spun to the bottom of the dip in the outline misfit (`cost`, `along`: one per spin, the motion's own
    first) that its own spin lies in, where that bottom is within DIP_STEPS and a single clear one: the handle's reach
    in the outline places the spin finer than a model's depth on a thin handle does (raycast mugs whose handle both
    views show had kept 5-15 deg from it; over 788 raycast pairs the mugs' median error 8.8 -> 7.2 deg, 5 more right
    and 3 fewer: the dip itself can lie a step off). A flat bottom (a handle hidden behind the body: spins within
    TIED_PX2 over more than two steps) tells nothing; nor does a hull off the outline."""
    n, k = len(cost), 0
    for _ in range(DIP_STEPS):
        lower = min((k - 1, k + 1), key=lambda j: cost[j % n])
        if not cost[lower % n] < cost[k % n]:
            break
        k = lower
    bottom = k % n
    if cost[(k - 1) % n] < cost[bottom] or cost[(k + 1) % n] < cost[bottom] or along[bottom] < MIN_ALONG:
        return motion  # still falling DIP_STEPS away: a far spin, which must fit clearly better (BETTER_BY_PX2)
    lo, hi = tied_run(cost <= cost[bottom] + TIED_PX2, bottom)
    if hi - lo > 1:
        return motion
    angle = _refined_angle(cost, bottom)
    return motion.turned_first(Rotation.from_rotvec(angle * handled.axis).as_matrix(), handled.centre)


def _refined_angle(cost: np.ndarray, index: int) -> float:
    """The spin [rad] at the vertex of the parabola through the costs (K,: one per STEP_DEG spin round the circle) at
    `index` and its two neighbours."""
    return np.radians(STEP_DEG) * (index + parabola_vertex(*cost[(index + np.array([-1, 0, 1])) % len(cost)]))


FIN_REACH_REL = (0.3, 0.6, 1.2)  # a handle the capture hid is looked for as a fin reaching these shares of the
# body's radius out of it (a mug's reaches about half its radius, a pan's more than all of it) ...
FIN_HEIGHTS = (0.25, 0.75)  # ... between these shares of its seen height
FIN_POINTS = 10  # along each of its reach and height
# the fin must take this share of the body's own misfit away: a fin fills any gap between a body of revolution drawn
# from its seen slices and the goal outline a little (raycast cans and bottles: 0.25-0.45 of it), a handle most of it
# (mugs whose capture hid theirs: 0.4-0.8)
FIN_SHARE = 0.5


def hidden_handle_spun(
    motion: Similarity, centre: np.ndarray, axis: np.ndarray, body: np.ndarray, outline: GoalOutline
) -> Similarity | None:
    """`motion` spun about the axis (`centre`, unit `axis`: camera frame) of a body of revolution standing in the
    capture (its `body`: the seen slices spun round, contact.symmetry.revolved) to where the goal outline shows a
    handle the capture did not: None where the outline shows none. A handle the capture did not see was behind the
    body, straight behind give or take the sector that hides it: a fin there (of a few reaches), spun with the body,
    must fit the outline clearly better than the body alone (BETTER_BY_PX2, and FIN_SHARE of its misfit), along it
    nearly all round (MIN_ALONG).
    Raycast mugs whose handle the capture hid had come out 100-180 deg off, read as bodies of revolution."""
    away = centre - (centre @ axis) * axis  # from the camera toward the axis, across it: the side it hid
    if np.linalg.norm(away) < 1e-6:
        return None
    away /= np.linalg.norm(away)
    off = body - centre
    heights = off @ axis
    radius = float(np.percentile(np.linalg.norm(off - np.outer(heights, axis), axis=1), 90))
    lo, hi = np.percentile(heights, 100 * np.array(FIN_HEIGHTS))
    spins = spins_about(axis, STEP_DEG)
    sets = [motion.apply(np.vstack([body, np.repeat(centre[None], FIN_POINTS**2, axis=0)]))]  # the body alone
    for reach in FIN_REACH_REL:
        r, h = np.meshgrid(np.linspace(radius, radius * (1 + reach), FIN_POINTS), np.linspace(lo, hi, FIN_POINTS))
        whole = np.vstack([body, centre + np.outer(r.ravel(), away) + np.outer(h.ravel(), axis)])
        sets += [motion.turned_first(g, centre).apply(whole) for g in spins]
    fits = outline.fits(np.stack(sets))
    alone, cost = fits.cost[0], fits.cost[1:].reshape(len(FIN_REACH_REL), len(spins))
    along = fits.along[1:].reshape(cost.shape)
    reach, best = np.unravel_index(int(np.argmin(cost)), cost.shape)
    if not alone - cost[reach, best] > max(BETTER_BY_PX2, FIN_SHARE * alone) or along[reach, best] < MIN_ALONG:
        return None
    angle = _refined_angle(cost[reach], int(best))
    return motion.turned_first(Rotation.from_rotvec(angle * axis).as_matrix(), centre)
