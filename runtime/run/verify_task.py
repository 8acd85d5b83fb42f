"""Verifying the tasks a rigid motion does not describe: a sweep's parts in the container, a lifted object.

Sweep: the parts are segmented again in the after capture (the same phrase; touching parts are one region,
counted by its area, pipeline.grounding.group), and each region is in the container when its centre lies over the
container's floor as first seen. The run succeeds when at least REQUIRED_FRACTION of the parts seen at the start
are inside; parts hidden behind the container's walls count as not inside (a failure is possible after a good
sweep, never the reverse).

Lift (the paper's "lifted clear"): the object is found again in the after capture, held in the fingers (which
hide part of it, so registering it against its first view is unreliable); it is lifted when its lowest seen
point rose at least LIFT_CLEAR_M and its seen centre is within the position tolerance of where the goal puts it.

Stood up (a bottle or can lying, stood on its base): its lying and standing views share little surface, and the
registration between them can fail its view-agreement check after a good stand-up (a black bottle: too little
shading to agree on). It is then judged by its axis: the axis of the body of revolution its seen points lie on,
after execution, within the rotation tolerance of the goal's (the first axis turned by the goal's motion), and
that axis's middle within the position tolerance of the goal's across the table (seen from another side, the
middle moves along the axis, which stands upright), and a bottle's wide end (its base) where the goal puts it: an
axis has no direction, so a bottle stood on its neck would otherwise pass.

Laid flat (a plate taken out of a rack, let go on its edge to tip over onto its face): the camera first saw one
face and now sees the other side of it, so no registration relates the two views. It is found again; it lies flat
when its seen top is no higher above the table than its thinnest extent as first seen (plus LAID_TOL_M), and it
is where the goal puts it when its seen middle (the middle of its extents: tines in front of it hide strips, which
pull a mean or median aside) is within the position tolerance of the goal's across the table (lying, its height
is the table's; the goal's is the grounded tilt's, a few degrees off over a plate's radius).
"""

from __future__ import annotations

import math

import numpy as np

from drivers.types import RGBDFrame
from pipeline.contact.symmetry import revolution_axis
from pipeline.grounding.group import count_in_container
from pipeline.grounding.upright import wide_end
from pipeline.perception.segmenter import Segmenter
from runtime.run.context import RunContext
from runtime.run.summary import GroupCountRecord, LaidCheckRecord, LiftCheckRecord, StoodCheckRecord, Verification
from safety.geometry import transform_points

REQUIRED_FRACTION = 0.8  # of the parts, inside the container (the paper's table sweeping: "swept into the dustpan")
LIFT_CLEAR_M = 0.01  # a lifted object's lowest seen point rose at least this much
LAID_TOL_M = 0.015  # a laid object's seen top is at most this much above its thickness


def verify_group(ctx: RunContext, after: RGBDFrame, segmenter: Segmenter) -> Verification:
    before, goal = ctx.frame0, ctx.goal
    if goal.mask_reference is None:
        return Verification(ok=False, reason=f"no container was segmented for '{goal.target}': nothing to count in")
    parts = [d.mask for d in segmenter.segment(after.rgb, goal.target, after.depth)]
    if parts:
        ctx.record.image("mask_after", _union(parts))
    count = count_in_container(
        depth0=before.depth,
        K0=before.intrinsics,
        T_base_camera0=before.T_base_camera,
        group0=goal.mask_init,
        container0=goal.mask_reference,
        depth1=after.depth,
        K1=after.intrinsics,
        T_base_camera1=after.T_base_camera,
        parts1=parts,
    )
    need = math.ceil(REQUIRED_FRACTION * count.total - 1e-9)
    ok = count.inside >= need
    reason = (
        f"{count.inside} of {count.total} {goal.target} in the {goal.reference} (need {need}); "
        f"{count.outside} seen elsewhere, in {len(count.regions)} region(s)"
    )
    record = GroupCountRecord(total=count.total, inside=count.inside, outside=count.outside, required=need)
    return Verification(ok=ok, reason=reason, group_count=record)


def _union(masks):
    out = masks[0].copy()
    for m in masks[1:]:
        out |= m
    return out


def base_points(frame: RGBDFrame, mask: np.ndarray) -> np.ndarray:
    """The frame's points under `mask` with a known depth, base frame."""
    valid = mask & np.isfinite(frame.depth)
    return transform_points(frame.T_base_camera, frame.intrinsics.unproject_depth_image(frame.depth)[valid])


class _NotMeasured(Exception):
    """The target cannot be measured in the after image (the reason says why)."""


def _target_clouds(ctx: RunContext, after: RGBDFrame, segmenter: Segmenter) -> tuple[np.ndarray, np.ndarray]:
    """The target's points in the base frame before (the planning capture) and after execution, its after-mask
    recorded; _NotMeasured unless it is found exactly once with enough depth in both."""
    goal = ctx.goal
    found = segmenter.segment(after.rgb, goal.target, after.depth)
    if len(found) != 1:
        raise _NotMeasured(f"target '{goal.target}' found {len(found)} times after execution")
    ctx.record.image("mask_after", found[0].mask)
    p0, p1 = base_points(ctx.frame0, goal.mask_init), base_points(after, found[0].mask)
    if len(p0) < 10 or len(p1) < 10:
        raise _NotMeasured(f"too few points with depth: {len(p0)} before, {len(p1)} after")
    return p0, p1


def verify_lift(ctx: RunContext, after: RGBDFrame, segmenter: Segmenter) -> Verification:
    try:
        p0, p1 = _target_clouds(ctx, after, segmenter)
    except _NotMeasured as e:
        return Verification(ok=False, reason=str(e))
    T = ctx.motion.T_base
    c0, c1 = p0.mean(axis=0), p1.mean(axis=0)
    goal_centre = T[:3, :3] @ c0 + T[:3, 3]
    error = float(np.linalg.norm(c1 - goal_centre))
    rise = float(np.percentile(p1[:, 2], 2) - np.percentile(p0[:, 2], 2))
    tol = ctx.profile.runtime.verify_position_tol_m
    ok = rise >= LIFT_CLEAR_M and error <= tol
    reason = (
        f"lowest point {'rose' if rise >= 0 else 'fell'} {abs(rise) * 1000:.0f} mm (need {LIFT_CLEAR_M * 1000:.0f}), "
        f"centre {error * 1000:.0f} mm from the goal (tolerance {tol * 1000:.0f})"
    )
    record = LiftCheckRecord(
        lowest_rise_m=rise, centre_rise_m=float(c1[2] - c0[2]), goal_rise_m=float(goal_centre[2] - c0[2]), error_m=error
    )
    return Verification(ok=ok, reason=("lifted clear: " if ok else "not lifted as asked: ") + reason, lift=record)


def _middle(points: np.ndarray) -> np.ndarray:
    """The middle of a cloud's extents along the base axes (2-98 %: depth bleeds at a thin object's edges)."""
    return 0.5 * (np.percentile(points, 2, axis=0) + np.percentile(points, 98, axis=0))


def _thickness(points: np.ndarray) -> float:
    """The thinnest extent of a cloud (5-95 % along its least principal direction)."""
    centred = points - points.mean(axis=0)
    along = centred @ np.linalg.svd(centred, full_matrices=False)[2][2]
    return float(np.percentile(along, 95) - np.percentile(along, 5))


def verify_laid(ctx: RunContext, after: RGBDFrame, segmenter: Segmenter) -> Verification:
    try:
        p0, p1 = _target_clouds(ctx, after, segmenter)
    except _NotMeasured as e:
        return Verification(ok=False, reason=str(e))
    T = ctx.motion.T_base
    goal_middle = T[:3, :3] @ _middle(p0) + T[:3, 3]
    error = float(np.linalg.norm(_middle(p1)[:2] - goal_middle[:2]))
    top, thickness = float(np.percentile(p1[:, 2], 98)), _thickness(p0)
    tol = ctx.profile.runtime.verify_position_tol_m
    ok = top <= thickness + LAID_TOL_M and error <= tol
    reason = (
        f"top {top * 1000:.0f} mm above the table (lying flat: at most {(thickness + LAID_TOL_M) * 1000:.0f}), "
        f"middle {error * 1000:.0f} mm from the goal's across the table (tolerance {tol * 1000:.0f})"
    )
    record = LaidCheckRecord(top_m=top, thickness_m=thickness, error_m=error)
    return Verification(ok=ok, reason=("laid flat: " if ok else "not laid as asked: ") + reason, laid=record)


def verify_stood(ctx: RunContext, after: RGBDFrame, mask_after: np.ndarray, unmeasured: str) -> Verification:
    """A stand-up whose achieved motion could not be measured (`unmeasured` says why), judged by the body's axis."""
    p0, p1 = base_points(ctx.frame0, ctx.goal.mask_init), base_points(after, mask_after)
    axis0, axis1 = revolution_axis(p0), revolution_axis(p1)
    if axis0 is None or axis1 is None:
        return Verification(ok=False, reason=f"{unmeasured}; and no body of revolution's axis was found to judge by")
    T = ctx.motion.T_base
    goal_direction, goal_point = T[:3, :3] @ axis0.direction, T[:3, :3] @ axis0.point + T[:3, 3]
    tilt = math.degrees(math.acos(min(1.0, abs(float(goal_direction @ axis1.direction)))))
    error = float(np.linalg.norm(axis1.point[:2] - goal_point[:2]))
    base0, base1 = wide_end(p0, axis0), wide_end(p1, axis1)  # a bottle's wide end; None: ends alike (a can)
    ends_swapped = base0 is not None and base1 is not None and float((T[:3, :3] @ base0) @ base1) < 0
    cfg = ctx.profile.runtime
    ok = tilt <= cfg.verify_rotation_tol_deg and error <= cfg.verify_position_tol_m and not ends_swapped
    reason = (
        ("it stands on the end the goal puts up; " if ends_swapped else "")
        + f"its axis {tilt:.0f} deg off the goal's (tolerance {cfg.verify_rotation_tol_deg:.0f}), "
        f"{error * 1000:.0f} mm from it across the table (tolerance {cfg.verify_position_tol_m * 1000:.0f}); "
        f"judged by the axis: {unmeasured}"
    )
    record = StoodCheckRecord(tilt_deg=tilt, error_m=error)
    return Verification(ok=ok, reason=("stood up: " if ok else "not stood up as asked: ") + reason, stood=record)
