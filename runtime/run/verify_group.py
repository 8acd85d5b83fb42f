"""Verifying a sweep: how many of the group's parts the after capture shows inside the container.

The parts are segmented again in the after capture (the same phrase; touching parts are one region, counted by
its area, pipeline.grounding.group), and each region is in the container when its centre lies within the
container's outline as first seen. The run succeeds when at least REQUIRED_FRACTION of the parts seen at the start
are inside; parts hidden behind the container's walls count as not inside (a failure is possible after a good
sweep, never the reverse).
"""

from __future__ import annotations

import math

from drivers.types import RGBDFrame
from pipeline.grounding.group import count_in_container
from pipeline.perception.segmenter import Segmenter
from runtime.run.context import RunContext
from runtime.run.summary import GroupCountRecord, Verification

REQUIRED_FRACTION = 0.8  # of the parts, inside the container (the paper's table sweeping: "swept into the dustpan")


def verify_group(ctx: RunContext, after: RGBDFrame, segmenter: Segmenter) -> Verification:
    before, goal = ctx.frame0, ctx.goal
    if goal.mask_reference is None:
        return Verification(ok=False, reason=f"no container was segmented for '{goal.target}': nothing to count in")
    parts = [d.mask for d in segmenter.segment(after.rgb, goal.target)]
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
