"""The Goal-VLA pipeline as run stages: each calls the module that owns the work and records what it decided.

No logic of the method lives here: reasoning is pipeline.reasoning, grounding pipeline.grounding, contact
pipeline.contact, motion planning and the gate motion + safety. A stage whose module is missing from the build
fails the run with a clear "not available" reason instead of pretending.
"""

from __future__ import annotations

import importlib
import logging
import time
import uuid
from typing import Any

import numpy as np

from pipeline.grounding.compare import compare, object_centre, object_symmetry, rotation_deg
from runtime.messaging.messages import PlanSummary
from runtime.run.context import RunContext, StageError, StageUnavailable, Verification

log = logging.getLogger(__name__)

CAMERA_STILL_MM, CAMERA_STILL_DEG = 2.0, 0.2  # verification needs both captures from one camera pose
MAX_CONTACTS = 3  # ranked contact decisions tried before planning gives up
PLAN_ATTEMPTS = 2  # planning attempts per contact (OMPL is randomised)


def require(stage: str, module: str, *names: str) -> Any:
    """Import `module` and return the named attributes, or StageUnavailable naming what is missing."""
    try:
        mod = importlib.import_module(module)
    except ImportError as e:
        raise StageUnavailable(f"{module} is not available in this build ({e}): the {stage} stage cannot run") from e
    missing = [n for n in names if not hasattr(mod, n)]
    if missing:
        raise StageUnavailable(f"{module} has no {', '.join(missing)}: the {stage} stage cannot run")
    values = tuple(getattr(mod, n) for n in names)
    return values[0] if len(values) == 1 else values


class PipelineStages:
    """Stateless between runs except for loaded backends (built once, on first use)."""

    def __init__(self) -> None:
        self._reasoner = None
        self._features = None
        self._segmenter = None

    # -- capture ------------------------------------------------------------------------------------------
    def _capture(self, ctx: RunContext, name: str):
        dev = ctx.devices
        frame = dev.capture(ctx.profile.camera.read_timeout_s)
        ctx.record.image(name, frame.rgb)
        np.savez_compressed(
            ctx.record.dir / f"{name}.npz",
            rgb=frame.rgb,
            depth=frame.depth,
            K=frame.intrinsics.K,
            T_base_camera=frame.T_base_camera,
        )
        return frame

    def capture(self, ctx: RunContext) -> None:
        ctx.frame0 = self._capture(ctx, "capture")
        if ctx.devices.world is not None:
            ctx.extras["truth_before"] = _object_centres(ctx.devices.world)

    # -- reasoning ----------------------------------------------------------------------------------------
    def reason(self, ctx: RunContext) -> None:
        build_reasoner = require("reasoning", "pipeline.reasoning.factory", "build_reasoner")
        ReasoningError = require("reasoning", "pipeline.reasoning.types", "ReasoningError")
        synthesize = require("reasoning", "pipeline.reasoning.reasoner", "synthesize")
        if self._reasoner is None:
            try:
                self._reasoner = build_reasoner(ctx.profile.pipeline)
            except RuntimeError as e:  # missing API keys, unusable model settings: the message names them
                raise StageError(str(e)) from None
        try:
            goal = self._reasoner.run(ctx.frame0, ctx.instruction, record_dir=str(ctx.record.dir / "reasoning"))
        except ReasoningError as e:
            raise StageError(str(e)) from None
        ctx.goal = goal
        ctx.record.image("goal", goal.rgb_goal)
        ctx.record.image(
            "overlay", synthesize(goal.rgb_init, goal.rgb_goal, goal.mask_goal, ctx.profile.pipeline.overlay_alpha)
        )
        ctx.record.image("masks", _mask_picture(goal.rgb_init, goal.mask_init, goal.mask_goal))
        ctx.record.note(
            reasoning={
                "target": goal.target,
                "prompt": goal.prompt,
                "validated": goal.validated,
                "iterations": len(goal.iterations),
                "seconds": goal.seconds,
            }
        )

    # -- grounding ----------------------------------------------------------------------------------------
    def _features_backend(self, ctx: RunContext):
        if self._features is None:
            features_from_config = require("grounding", "pipeline.perception.features", "features_from_config")
            self._features = features_from_config(ctx.profile.pipeline)
        return self._features

    def ground(self, ctx: RunContext) -> None:
        ground, GroundingInput = require("grounding", "pipeline.grounding.ground", "ground", "GroundingInput")
        goal, frame = ctx.goal, ctx.frame0
        inp = GroundingInput.from_goal(frame, goal)
        motion = ground(
            inp, self._features_backend(ctx), ctx.profile.pipeline.grounding, T_base_camera=frame.T_base_camera
        )
        ctx.record.note(object_motion=_motion_json(motion))
        if not motion.ok:
            raise StageError(f"grounding refused: {motion.reason}")
        ctx.motion = motion

    # -- planning -----------------------------------------------------------------------------------------
    def contact_candidates(self, ctx: RunContext, chain) -> list:
        """The contact stage's ranked decisions as motion.manipulation.phases.ContactPoses."""
        candidates = require("contact", "runtime.run.contact", "contact_candidates")
        return candidates(ctx, chain)

    def plan(self, ctx: RunContext) -> PlanSummary:
        """The best-ranked contact whose whole manipulation plans and passes the gate (up to MAX_CONTACTS, each
        PLAN_ATTEMPTS times)."""
        Chain, plan_manipulation = require("planning", "motion.manipulation.phases", "Chain", "plan_manipulation")
        draw_tcp_poses = require("planning", "runtime.run.overlay", "draw_tcp_poses")
        chain = Chain(ctx)
        refusals = []
        attempts = [p for p in self.contact_candidates(ctx, chain)[:MAX_CONTACTS] for _ in range(PLAN_ATTEMPTS)]
        for poses in attempts:  # the sampling planner may find a better path on a second try
            try:
                plan = plan_manipulation(chain, poses)
                break
            except StageError as e:
                refusals.append(f"{poses.source or poses.mode}: {e}")
        else:
            ctx.record.note(planning_refusals=refusals)
            raise StageError("no contact could be planned:\n  " + "\n  ".join(refusals))
        ctx.record.note(planning_refusals=refusals, contact_used=poses.source)
        ctx.trajectory = plan
        frame = ctx.frame0
        ctx.record.image("plan", draw_tcp_poses(frame.rgb, frame.intrinsics, frame.T_base_camera, plan.tcp_waypoints))
        motion = ctx.motion.T_base if ctx.motion is not None else np.eye(4)
        return PlanSummary(
            stamp_s=time.time(),
            plan_id=uuid.uuid4().hex[:10],
            run_id=ctx.record.run_id,
            instruction=ctx.instruction,
            mode=poses.mode,
            duration_s=plan.duration_s,
            peak_joint_speed_rad_s=plan.peak_joint_speed_rad_s,
            min_clearance_m=ctx.profile.safety.padding_m,
            samples=plan.samples,
            gate_ok=True,
            object_motion={
                "translation_m": np.round(motion[:3, 3], 3).tolist(),
                "rotation_deg": round(rotation_deg(motion[:3, :3]), 1),
            },
        )

    # -- execution ----------------------------------------------------------------------------------------
    def execute(self, ctx: RunContext) -> None:
        Executor, ExecutorConfig, ExecutionRefused = require(
            "execution", "motion.executor", "Executor", "ExecutorConfig", "ExecutionRefused"
        )
        MotionLimits = require("execution", "motion.limits", "MotionLimits")
        dev, profile, plan = ctx.devices, ctx.profile, ctx.trajectory
        limits = MotionLimits.from_config(profile.safety, _robot_spec())
        executor = Executor(dev.arm, ExecutorConfig.from_configs(profile.robot, profile.safety), limits, dev.gripper)
        ctx.extras["executor"] = executor
        reports = []
        for name, approved in zip(plan.phase_names, plan.phases, strict=True):
            if ctx.cancel.is_set():
                return
            try:
                report = executor.execute(approved)
            except ExecutionRefused as e:
                raise StageError(f"{name} phase refused by the executor: {e}") from None
            reports.append(
                {
                    "phase": name,
                    "status": report.status,
                    "reason": report.reason,
                    "ticks": report.ticks,
                    "late_ticks": report.late_ticks,
                    "jitter_p99_s": report.jitter.p99_s,
                    "max_tracking_error_rad": report.max_tracking_error_rad,
                    "gripper": [
                        {"kind": g.event.kind, "width_m": g.width_m, "grasped": g.grasped} for g in report.gripper
                    ],
                }
            )
            ctx.record.note(execution=reports)
            if report.status != "completed":
                raise StageError(f"{name} phase {report.status}: {report.reason}")
            if plan.poses.mode == "grasp" and any(
                g.event.kind == "close" and g.grasped is False for g in report.gripper
            ):
                raise StageError(f"{name} phase: the gripper closed on nothing (object not grasped)")

    def stop_motion(self, ctx: RunContext, reason: str, graceful: bool) -> None:
        executor = ctx.extras.get("executor")
        if executor is None or not executor.running:
            return
        if graceful:
            executor.abort(reason)
            try:
                executor.wait(timeout_s=2.0)
                return
            except TimeoutError:
                log.warning("executor did not come to rest within 2 s of an abort: stopping at once")
        executor.estop(reason)

    # -- verification -------------------------------------------------------------------------------------
    def verify(self, ctx: RunContext) -> Verification:
        ground, GroundingInput = require("verification", "pipeline.grounding.ground", "ground", "GroundingInput")
        build_segmenter = require("verification", "pipeline.reasoning.factory", "build_segmenter")
        time.sleep(0.3)  # let the object settle after release
        frame1 = ctx.frame1 = self._capture(ctx, "after")
        if ctx.devices.world is not None:
            ctx.extras["truth_after"] = _object_centres(ctx.devices.world)
            ctx.record.note(sim_truth=_truth(ctx))
        moved_mm, moved_deg = camera_moved(ctx.frame0.T_base_camera, frame1.T_base_camera)
        if moved_mm > CAMERA_STILL_MM or moved_deg > CAMERA_STILL_DEG:
            return Verification(
                False,
                f"the camera moved {moved_mm:.0f} mm / {moved_deg:.1f} deg between the captures: verification compares "
                "two views from one pose (a camera on the arm must capture again where it first did)",
            )
        if self._segmenter is None:
            self._segmenter = build_segmenter(ctx.profile.pipeline)
        detections = self._segmenter.segment(frame1.rgb, ctx.goal.target)
        if len(detections) != 1:
            return Verification(False, f"target '{ctx.goal.target}' found {len(detections)} times after execution")
        mask1 = detections[0].mask
        ctx.record.image("mask_after", mask1)
        frame0, mask0 = ctx.frame0, ctx.goal.mask_init
        anchor = getattr(ctx.goal, "mask_anchor", None)  # a hinged part: measured as a turn about it, like its goal
        points = frame0.intrinsics.unproject_depth_image(frame0.depth)[mask0 & np.isfinite(frame0.depth)]
        symmetry = None if anchor is not None else object_symmetry(points)
        after = None
        if symmetry is not None and symmetry.axis is None:  # a ball: its centre is all a registration could tell
            after = object_symmetry(
                frame1.intrinsics.unproject_depth_image(frame1.depth)[mask1 & np.isfinite(frame1.depth)]
            )
        if after is not None and after.axis is None:
            achieved_R, achieved_t = np.eye(3), after.centre - symmetry.centre
            ctx.record.note(achieved_motion={"ok": True, "ball_centre_shift_m": achieved_t.tolist()})
        else:
            inp = GroundingInput(
                frame0.rgb, frame0.depth, mask0, frame1.rgb, frame1.depth, "depth", mask1, frame0.intrinsics, anchor
            )
            achieved = ground(
                inp, self._features_backend(ctx), ctx.profile.pipeline.grounding, T_base_camera=frame0.T_base_camera
            )
            ctx.record.note(achieved_motion=_motion_json(achieved))
            if not achieved.ok:
                return Verification(False, f"could not measure the achieved motion: {achieved.reason}")
            achieved_R, achieved_t = achieved.R, achieved.t
        goal = ctx.motion
        cfg = ctx.profile.runtime
        return compare(
            goal.R,
            goal.t,
            achieved_R,
            achieved_t,
            object_centre(points),
            frame0.T_base_camera[:3, :3],
            cfg.verify_position_tol_m,
            cfg.verify_rotation_tol_deg,
            symmetry,
        )


def camera_moved(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(mm, deg) between two camera poses."""
    return 1000 * float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])), rotation_deg(T_a[:3, :3].T @ T_b[:3, :3])


def _robot_spec():
    from drivers.description import load_robot_spec

    return load_robot_spec()


def _motion_json(motion) -> dict:
    out = motion.to_json()
    if motion.ok and motion.T_base_camera is not None:
        T = motion.T_base
        out["translation_base_m"] = T[:3, 3].tolist()
    return out


def _mask_picture(rgb: np.ndarray, mask_init: np.ndarray, mask_goal: np.ndarray) -> np.ndarray:
    """The initial image dimmed, the target now in red and at the goal in green."""
    out = (rgb.astype(np.float32) * 0.4).astype(np.uint8)
    out[mask_init] = (0.5 * out[mask_init] + [127, 0, 0]).astype(np.uint8)
    out[mask_goal] = (0.5 * out[mask_goal] + [0, 127, 0]).astype(np.uint8)
    return out


def _object_centres(world) -> dict[str, np.ndarray]:
    """Each object's centre (the mean of its shapes' centres: on the axis of a body of revolution, so an unseen
    turn about that axis does not move it), and each hinge's angle under "<hinge joint> [deg]"."""
    from drivers.sim.gl import mujoco

    m, d = world.model, world.data
    out = {}
    with world.lock:
        for o in world.scene.objects:
            root = m.body(o.name).id
            out[o.name] = d.geom_xpos[np.flatnonzero(m.body_rootid[m.geom_bodyid] == root)].mean(axis=0)
            for j in np.flatnonzero(m.body_rootid[m.jnt_bodyid] == root):
                if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:  # an object's part: a lid
                    out[f"{m.joint(j).name} [deg]"] = np.array([np.degrees(d.qpos[m.jnt_qposadr[j]])])
    return out


def _truth(ctx: RunContext) -> dict:
    """Simulator ground truth for the record and benchmarks (never used to decide success): how far every object
    moved, hinge angles, and for a whole object that was moved, how far its centre ended from where the goal
    motion puts it (a hinged part's truth is its hinge angle)."""
    before, after = ctx.extras["truth_before"], ctx.extras["truth_after"]
    moved = {n: float(np.linalg.norm(after[n] - before[n])) for n in before if not n.endswith("[deg]")}
    out: dict = {"object_displacement_m": moved}
    out |= {n: float(after[n][0]) for n in after if n.endswith("[deg]")}
    motion = getattr(ctx, "motion", None)
    hinged = getattr(ctx.goal, "mask_anchor", None) is not None
    if moved and not hinged and motion is not None and motion.ok and motion.T_base_camera is not None:
        name = max(moved, key=moved.get)
        T = motion.T_base
        goal = T[:3, :3] @ before[name] + T[:3, 3]
        out |= {"target": name, "target_goal_error_m": float(np.linalg.norm(after[name] - goal))}
    return out
