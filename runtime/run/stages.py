"""The Goal-VLA pipeline as run stages: each calls the module that owns the work and records what it decided.

No logic of the method lives here: reasoning is pipeline.reasoning, grounding pipeline.grounding, contact
pipeline.contact (runtime.run.contact asks it), the manipulation motion.manipulation with the gate, verification
pipeline.grounding's achieved motion and comparison (runtime.run.verification).
"""

from __future__ import annotations

import logging
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from drivers.description import load_robot_spec
from drivers.types import RGBDFrame
from motion.clock import Clock
from motion.executor import ExecutionRefused, Executor, ExecutorConfig
from motion.limits import MotionLimits
from motion.manipulation.chain import ManipulationChain, ManipulationRefused
from motion.manipulation.phases import ManipulationPlan, plan_lift, plan_manipulation
from pipeline.contact.clouds import SceneClouds, scene_clouds
from pipeline.contact.types import ContactPlan
from pipeline.grounding.compare import rotation_deg
from pipeline.grounding.ground import ground
from pipeline.grounding.group import ground_group
from pipeline.grounding.level import kept_level
from pipeline.grounding.settle import settled
from pipeline.grounding.types import GroundingInput
from pipeline.grounding.upright import stood_on_its_base, stood_straight
from pipeline.perception.features import FeatureExtractor, features_from_config
from pipeline.perception.segmenter import Segmenter
from pipeline.reasoning.factory import build_reasoner, build_segmenter
from pipeline.reasoning.reasoner import Reasoner, synthesize
from pipeline.reasoning.types import ReasoningError
from runtime.devices import Devices
from runtime.messaging.messages import PlanSummary
from runtime.run.contact import COMES_TO_REST, PUTS_DOWN, contact_plans, instruction_action
from runtime.run.context import RunContext, StageError
from runtime.run.overlay import draw_tcp_poses
from runtime.run.second_look import look_again
from runtime.run.summary import (
    LookRecord,
    MotionRecord,
    PhaseRecord,
    PlanningRecord,
    ReasoningRecord,
    Verification,
)
from runtime.run.sweep import plan_sweep_stage
from runtime.run.verification import verify_run
from safety.robot_model import RobotModel

log = logging.getLogger(__name__)

MAX_CONTACTS = 3  # ranked contact decisions tried before planning gives up
GRASPING_MODES = ("grasp", "sweep")  # a close in these grasps something (an object, a tool): closing on nothing stops
PLAN_ATTEMPTS = 2  # planning attempts per contact when a path search failed (OMPL is randomised)
SETTLE_S = 0.3  # after the last phase, before the capture that verifies: the object comes to rest
ABORT_REST_S = 2.0  # an operator abort: how long the executor may take to come to rest on its path


class CaptureListener(Protocol):
    """Told of every capture a run takes ("capture" before, "look1", ... right before moving, "after" for
    verification), right after it."""

    def on_capture(self, name: str, ctx: RunContext) -> None: ...


class PipelineStages:
    """Stateless between runs except for loaded backends (built once, on first use)."""

    def __init__(
        self, listeners: Sequence[CaptureListener] = (), clock: Callable[[Devices], Clock] | None = None
    ) -> None:
        """clock: the executor's clock for the run's devices (default the wall clock); a stepped simulator's
        (drivers.sim.SteppedClock) makes a run independent of the machine's load, for benches."""
        self.listeners = tuple(listeners)
        self.clock = clock
        self._reasoner: Reasoner | None = None
        self._features: FeatureExtractor | None = None
        self._segmenter: Segmenter | None = None

    # -- capture ------------------------------------------------------------------------------------------
    def _capture(self, ctx: RunContext, name: str) -> RGBDFrame:
        frame = ctx.devices.capture(ctx.profile.camera.read_timeout_s)
        ctx.record.image(name, frame.rgb)
        np.savez_compressed(
            ctx.record.dir / f"{name}.npz",
            rgb=frame.rgb,
            depth=frame.depth,
            K=frame.intrinsics.K,
            T_base_camera=frame.T_base_camera,
        )
        for listener in self.listeners:
            listener.on_capture(name, ctx)
        return frame

    def capture(self, ctx: RunContext) -> None:
        ctx.frame0 = self._capture(ctx, "capture")

    # -- reasoning ----------------------------------------------------------------------------------------
    def reason(self, ctx: RunContext) -> None:
        if self._reasoner is None:
            try:
                self._reasoner = build_reasoner(ctx.profile.pipeline)
            except RuntimeError as e:  # missing API keys, unusable model settings: the message names them
                raise StageError(str(e)) from e
        try:
            folder = "reasoning" if ctx.basis == "capture" else f"reasoning_{ctx.basis}"  # again after a change
            goal = self._reasoner.run(ctx.frame0, ctx.instruction, record_dir=str(ctx.record.dir / folder))
        except ReasoningError as e:
            raise StageError(str(e)) from e
        ctx.goal = goal
        ctx.record.image("goal", goal.rgb_goal)
        ctx.record.image(
            "overlay", synthesize(goal.rgb_init, goal.rgb_goal, goal.mask_goal, ctx.profile.pipeline.overlay_alpha)
        )
        ctx.record.image("masks", _mask_picture(goal.rgb_init, goal.mask_init, goal.mask_goal))
        ctx.record.summary.reasoning = ReasoningRecord(
            target=goal.target,
            prompt=goal.prompt,
            validated=goal.validated,
            iterations=len(goal.iterations),
            seconds=goal.seconds,
        )

    # -- grounding ----------------------------------------------------------------------------------------
    def _features_backend(self, ctx: RunContext) -> FeatureExtractor:
        if self._features is None:
            self._features = features_from_config(ctx.profile.pipeline)
        return self._features

    def ground(self, ctx: RunContext) -> None:
        frame = ctx.frame0
        if ctx.goal.group_size is not None:  # several like parts: their centroid's motion
            motion = ground_group(
                GroundingInput.from_goal(frame, ctx.goal), ctx.profile.pipeline.grounding, frame.T_base_camera
            )
        else:
            motion = ground(
                GroundingInput.from_goal(frame, ctx.goal),
                self._features_backend(ctx),
                ctx.profile.pipeline.grounding,
                T_base_camera=frame.T_base_camera,
            )
        if ctx.goal.group_size is None:
            points = frame.intrinsics.unproject_depth_image(frame.depth)
            known = np.isfinite(frame.depth)
            seen = points[ctx.goal.mask_init & known]
            up = frame.T_base_camera[:3, :3].T @ np.array([0.0, 0.0, 1.0])
            motion = stood_on_its_base(motion, seen, up)
            if instruction_action(ctx.instruction) == "stand_up":
                motion = stood_straight(motion, seen, up)
            if instruction_action(ctx.instruction) in PUTS_DOWN:
                motion = kept_level(motion, seen, up)
            if instruction_action(ctx.instruction) in COMES_TO_REST:
                table = -float(frame.T_base_camera[2, 3])  # the table top (base z = 0) along `up`
                motion = settled(motion, seen, points[~ctx.goal.mask_init & known], up, table)
        ctx.record.summary.object_motion = MotionRecord.of(motion)
        if not motion.ok:
            raise StageError(f"grounding refused: {motion.reason}")
        ctx.motion = motion

    # -- planning -----------------------------------------------------------------------------------------
    def contacts(
        self, ctx: RunContext, clouds: SceneClouds, robot: RobotModel, q_start: np.ndarray
    ) -> list[ContactPlan]:
        """The contact stage's ranked decisions (the sim's ground-truth grasp overrides this)."""
        return contact_plans(ctx, clouds, robot, q_start)

    def plan(self, ctx: RunContext) -> PlanSummary:
        """The best-ranked contact whose whole manipulation plans and passes the gate (up to MAX_CONTACTS, each
        PLAN_ATTEMPTS times)."""
        profile, frame = ctx.profile, ctx.frame0
        robot = RobotModel()
        q_start = ctx.devices.arm.read_state().q
        action = instruction_action(ctx.instruction)
        if action == "sweep":
            contact, manipulation = plan_sweep_stage(ctx, robot, q_start)
        else:
            phases = plan_lift if action == "lift" else plan_manipulation
            contact, manipulation = self._plan_contact(ctx, robot, q_start, phases)
        ctx.contact, ctx.manipulation = contact, manipulation
        poses = draw_tcp_poses(frame.rgb, frame.intrinsics, frame.T_base_camera, manipulation.tcp_waypoints)
        ctx.record.image("plan", poses)
        motion = ctx.motion.T_base
        return PlanSummary(
            stamp_s=time.time(),
            plan_id=uuid.uuid4().hex[:10],
            run_id=ctx.record.run_id,
            instruction=ctx.instruction,
            mode=contact.mode if action != "lift" else "lift",
            duration_s=manipulation.duration_s,
            peak_joint_speed_rad_s=manipulation.peak_joint_speed_rad_s,
            min_clearance_m=profile.safety.padding_m,
            samples=manipulation.samples,
            gate_ok=True,
            object_motion={
                "translation_m": np.round(motion[:3, 3], 3).tolist(),
                "rotation_deg": round(rotation_deg(motion[:3, :3]), 1),
            },
        )

    def _plan_contact(
        self, ctx: RunContext, robot: RobotModel, q_start: np.ndarray, phases: Callable
    ) -> tuple[ContactPlan, ManipulationPlan]:
        """The best-ranked contact whose manipulation (`phases` of it) plans and passes the gate, and that
        manipulation."""
        profile, frame = ctx.profile, ctx.frame0
        clouds = ctx.clouds = scene_clouds(
            frame, ctx.goal.mask_init, robot, q_start, workspace=profile.safety.workspace
        )
        chain = ManipulationChain(
            robot,
            robot_config=profile.robot,
            safety=profile.safety,
            motion=profile.motion,
            q_start=q_start,
            scene=clouds.scene,
            target=clouds.target,
        )
        refusals = []
        manipulation = None
        for contact in self.contacts(ctx, clouds, robot, q_start)[:MAX_CONTACTS]:
            for attempt in range(1, PLAN_ATTEMPTS + 1):
                try:
                    manipulation = phases(chain, contact)
                    break
                except ManipulationRefused as e:
                    refusal = f"{contact.source}: {e}" + (f" ({attempt} attempts)" if attempt > 1 else "")
                    if attempt > 1:
                        refusals.pop()
                    refusals.append(refusal)
                    if not e.searched:  # the same on every attempt: only a path search may find one next time
                        break
            if manipulation is not None:
                break
        else:
            ctx.record.summary.planning = PlanningRecord(refusals=refusals)
            raise StageError("no contact could be planned:\n  " + "\n  ".join(refusals))
        ctx.record.summary.planning = PlanningRecord(contact_used=contact.source, refusals=refusals)
        return contact, manipulation

    # -- the second look ----------------------------------------------------------------------------------
    def recheck(self, ctx: RunContext) -> LookRecord:
        name = f"look{len(ctx.record.summary.second_look) + 1}"
        look = self._capture(ctx, name)
        return look_again(ctx, look, name, self._segmenter_backend(ctx), self._features_backend(ctx))

    def _segmenter_backend(self, ctx: RunContext) -> Segmenter:
        if self._segmenter is None:
            self._segmenter = build_segmenter(ctx.profile.pipeline)
        return self._segmenter

    # -- execution ----------------------------------------------------------------------------------------
    def execute(self, ctx: RunContext) -> None:
        dev, profile, manipulation = ctx.devices, ctx.profile, ctx.manipulation
        limits = MotionLimits.from_config(profile.safety, load_robot_spec())
        clock = self.clock(dev) if self.clock is not None else None
        config = ExecutorConfig.from_configs(profile.robot, profile.safety)
        executor = Executor(dev.arm, config, limits, dev.gripper, clock=clock)
        ctx.executor = executor
        reports: list[PhaseRecord] = []
        for name, approved in zip(manipulation.phase_names, manipulation.phases, strict=True):
            if ctx.cancel.is_set():
                return
            try:
                report = executor.execute(approved)
            except ExecutionRefused as e:
                raise StageError(f"{name} phase refused by the executor: {e}") from e
            ctx.executed.append((name, report))
            reports.append(PhaseRecord.of(name, report))
            ctx.record.summary.execution = list(reports)
            if report.status != "completed":
                raise StageError(f"{name} phase {report.status}: {report.reason}")
            if manipulation.contact.mode in GRASPING_MODES and any(
                g.event.kind == "close" and g.grasped is False for g in report.gripper
            ):
                raise StageError(f"{name} phase: the gripper closed on nothing (object not grasped)")

    def stop_motion(self, ctx: RunContext, reason: str, graceful: bool) -> None:
        executor = ctx.executor
        if executor is None or not executor.running:
            return
        if graceful:
            executor.abort(reason)
            try:
                executor.wait(timeout_s=ABORT_REST_S)
                return
            except TimeoutError:
                log.warning("executor did not come to rest within %.0f s of an abort: stopping at once", ABORT_REST_S)
        executor.estop(reason)

    # -- verification -------------------------------------------------------------------------------------
    def verify(self, ctx: RunContext) -> Verification:
        if self.clock is None:
            time.sleep(SETTLE_S)  # the object comes to rest after the release (physical time: nothing to wait on)
        else:
            clock = self.clock(ctx.devices)
            clock.sleep_until(clock.now() + SETTLE_S)
        after = ctx.frame1 = self._capture(ctx, "after")
        return verify_run(ctx, after, self._segmenter_backend(ctx), self._features_backend(ctx))


def _mask_picture(rgb: np.ndarray, mask_init: np.ndarray, mask_goal: np.ndarray) -> np.ndarray:
    """The initial image dimmed, the target now in red and at the goal in green."""
    out = (rgb.astype(np.float32) * 0.4).astype(np.uint8)
    out[mask_init] = (0.5 * out[mask_init] + [127, 0, 0]).astype(np.uint8)
    out[mask_goal] = (0.5 * out[mask_goal] + [0, 127, 0]).astype(np.uint8)
    return out
