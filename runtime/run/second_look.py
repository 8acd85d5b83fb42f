"""The second look right before moving: capture again and compare with the capture the plan was made from.

A plan is made from one capture, and the confirmation may come minutes later; a ball may roll, a person may
nudge a bottle or put a cup down. So right before EXECUTING the run looks again (same camera pose) and finds the
regions whose depth changed (pipeline.perception.scene_change), within the workspace:
- none: the plan holds (`still`), at the cost of one capture and one image difference;
- only where the target was or now is: the target is found again and its motion since is measured the way
  verification measures one (pipeline.grounding.achieved). Within the tolerance (a few mm and degrees) the plan
  holds. Beyond it the goal stays where the goal image put the object, so the grounded motion is re-based on the
  look (motion after the drift = goal motion composed with the drift undone) and the run plans again (`replan`);
- anywhere else (a neighbour moved, something new stands in the scene), or the target cannot be found once or
  measured: everything from the goal image on is made again from the look (`reason`), since the goal and the
  obstacles it was planned among may no longer hold.
The run loop bounds how often it goes back (runtime.second_look.max_replans) and refuses to move beyond that.
"""

from __future__ import annotations

import time
from dataclasses import replace

import cv2
import numpy as np

from drivers.types import RGBDFrame
from pipeline.grounding.achieved import measure_achieved
from pipeline.grounding.compare import hidden_turns_out, rotation_deg
from pipeline.perception.features import FeatureExtractor
from pipeline.perception.scene_change import ChangedRegion, depth_changes
from pipeline.perception.segmenter import Segmenter
from runtime.run.context import RunContext, StageError
from runtime.run.summary import ChangeRecord, LookRecord, MotionRecord
from runtime.run.verification import CAMERA_STILL_DEG, CAMERA_STILL_MM, camera_moved, find_target_again
from safety.geometry import transform_points

TARGET_ZONE_PX = 7  # a changed region this close to the target's pixels (then or now) is the target's
ON_TARGET = 0.5  # ... when at least this share of it lies there


def workspace_pixels(frame: RGBDFrame, box_min: np.ndarray, box_max: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels whose point lies inside the workspace box (base frame)."""
    points = frame.intrinsics.unproject_depth_image(frame.depth).reshape(-1, 3)
    base = transform_points(frame.T_base_camera, np.nan_to_num(points, nan=1e6))
    inside = np.all((base >= box_min) & (base <= box_max), axis=1)
    return inside.reshape(frame.depth.shape)


def look_again(
    ctx: RunContext, look: RGBDFrame, name: str, segmenter: Segmenter, features: FeatureExtractor
) -> LookRecord:
    """Compare the look with the plan's capture (ctx.frame0) and decide; a `replan` re-bases the goal motion and
    a `reason` the capture in ctx (ctx.frame0, ctx.basis) before returning. StageError when the camera moved."""
    t0 = time.perf_counter()
    before, basis, goal, cfg = ctx.frame0, ctx.basis, ctx.goal, ctx.profile.runtime.second_look
    moved_mm, moved_deg = camera_moved(before.T_base_camera, look.T_base_camera)
    if moved_mm > CAMERA_STILL_MM or moved_deg > CAMERA_STILL_DEG:
        raise StageError(
            f"the camera moved {moved_mm:.0f} mm / {moved_deg:.1f} deg since the capture the plan was made from: "
            "the second look compares two views from one pose"
        )
    box = ctx.profile.safety.workspace
    lo, hi = np.asarray(box.min_m), np.asarray(box.max_m)
    within = workspace_pixels(before, lo, hi) | workspace_pixels(look, lo, hi)
    regions = depth_changes(
        before.depth,
        look.depth,
        before.intrinsics,
        min_change_m=cfg.depth_change_m,
        min_area_m2=cfg.min_area_m2,
        within=within,
    )

    def record(decision: str, reason: str, changes=(), **measured) -> LookRecord:
        return LookRecord(
            capture=name,
            compared_with=basis,
            changes=list(changes),
            decision=decision,
            reason=reason,
            seconds=round(time.perf_counter() - t0, 3),
            **measured,
        )

    if not regions:
        return record("still", f"nothing moved since {basis} (depth within {cfg.depth_change_m * 1000:.0f} mm)")
    detections = find_target_again(
        segmenter, look.rgb, goal.target, before.rgb, goal.mask_init, look.depth, goal.mask_anchor
    )
    if len(detections) != 1:
        changes = [_change(r, "scene", look) for r in regions]
        _rebase_capture(ctx, look, name)
        return record(
            "reason",
            f"the scene changed ({regions[0].describe(look.T_base_camera)}) and the target '{goal.target}' is found "
            f"{len(detections)} times now: the goal is made again from {name}",
            changes,
        )
    mask_now = detections[0].mask
    zone = cv2.dilate(
        (goal.mask_init | mask_now).astype(np.uint8), np.ones((2 * TARGET_ZONE_PX + 1,) * 2, np.uint8)
    ).astype(bool)
    on_target = [(zone & r.mask).sum() >= ON_TARGET * r.mask.sum() for r in regions]
    changes = [_change(r, "target" if t else "scene", look) for r, t in zip(regions, on_target, strict=True)]
    elsewhere = [r for r, t in zip(regions, on_target, strict=True) if not t]
    if elsewhere:
        _rebase_capture(ctx, look, name)
        return record(
            "reason",
            f"something besides the target moved since {basis}: "
            f"{elsewhere[0].describe(look.T_base_camera)}"
            + (f" (and {len(elsewhere) - 1} more regions)" if len(elsewhere) > 1 else "")
            + f"; the goal is made again from {name}",
            changes,
        )
    drift = measure_achieved(
        before=before,
        mask_before=goal.mask_init,
        after=look,
        mask_after=mask_now,
        anchor_before=goal.mask_anchor,
        features=features,
        config=ctx.profile.pipeline.grounding,
        expected=(np.eye(3), np.zeros(3)),  # still where it was, up to a turn no view shows
    )
    drift_record = None if drift.registration is None else MotionRecord.of(drift.registration)
    if not drift.ok:
        _rebase_capture(ctx, look, name)
        return record(
            "reason",
            f"the target '{goal.target}' moved and its motion could not be measured ({drift.reason}): the goal is "
            f"made again from {name}",
            changes,
            drift=drift_record,
        )
    shift, turn = _shift_turn(drift)
    measured = {"target_shift_m": round(shift, 4), "target_turn_deg": round(turn, 2), "drift": drift_record}
    what = f"the target '{goal.target}' moved {shift * 1000:.0f} mm and turned {turn:.1f} deg since {basis}"
    if shift <= cfg.target_shift_m and turn <= cfg.target_turn_deg:
        tolerance = f"{cfg.target_shift_m * 1000:.0f} mm / {cfg.target_turn_deg:.0f} deg"
        return record("still", f"{what}, within {tolerance}: the plan holds", changes, **measured)
    _rebase_motion(ctx, look, name, mask_now, drift.R, drift.t)
    return record("replan", f"{what}: its goal motion is re-based on {name} and planned again", changes, **measured)


def _change(region: ChangedRegion, what: str, look: RGBDFrame) -> ChangeRecord:
    at = transform_points(look.T_base_camera, region.centre_camera[None])[0]
    return ChangeRecord(
        what=what,
        area_cm2=round(region.area_m2 * 1e4, 2),
        max_change_mm=round(region.max_change_m * 1000, 1),
        at_base_m=np.round(at, 3).tolist(),
    )


def _shift_turn(drift) -> tuple[float, float]:
    """How far the target's centre moved [m] and how far it turned [deg], without the turns its symmetry hides."""
    c = drift.centre_camera if drift.symmetry is None else drift.symmetry.centre
    shift = float(np.linalg.norm(drift.R @ c + drift.t - c))
    return shift, rotation_deg(hidden_turns_out(drift.R, drift.symmetry))


def _rebase_capture(ctx: RunContext, look: RGBDFrame, name: str) -> None:
    """Everything from the goal image on is made again from the look."""
    ctx.frame0, ctx.basis = look, name
    ctx.goal = ctx.motion = ctx.contact = ctx.manipulation = ctx.plan = None


def _rebase_motion(
    ctx: RunContext, look: RGBDFrame, name: str, mask_now: np.ndarray, R_drift: np.ndarray, t_drift: np.ndarray
) -> None:
    """The goal stays where the goal image put the object: from the look, the motion is the goal motion after
    the drift is undone (x_goal = R_g R_d^T (x_now - t_d) + t_g, camera frame)."""
    motion = ctx.motion
    R = motion.R @ R_drift.T
    t = motion.t - R @ t_drift
    symmetry = None if motion.symmetry is None else motion.symmetry.moved(R_drift, t_drift)
    ctx.motion = replace(motion, R=R, t=t, details={**motion.details, "rebased_on": name}, symmetry=symmetry)
    ctx.goal = replace(ctx.goal, rgb_init=look.rgb, mask_init=mask_now)
    ctx.frame0, ctx.basis = look, name
    ctx.contact = ctx.manipulation = ctx.plan = None
    ctx.record.summary.object_motion = MotionRecord.of(ctx.motion)
