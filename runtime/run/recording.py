"""run.rrd: the whole run as a Rerun recording, written once the run has ended (never while the arm moves).

What it holds (entity paths in ENTITIES, base frame = the 3D view's world; one timeline, `run_time`, seconds from
the run's start):
- the capture, goal, overlay and masks images, and the camera (pinhole at T_base_camera) with the capture;
- the scene cloud and the target's initial and goal clouds (the grounded motion applied), and the object motion
  as an arrow from the target's centre to where the motion puts it;
- the pre-contact, contact and goal gripper poses (and the via and place poses);
- the robot's links from the project's URDF (Pinocchio forward kinematics of the description) following the
  measured joints, the planned and executed joint trajectories as scalars, the planned and executed TCP paths;
- the states, the gate's verdict on each phase and the gripper events as text on the timeline.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from drivers.description.spec import Box, Capsule, Cylinder
from motion.executor import ExecutorConfig
from runtime.run.summary import RunSummary
from runtime.run.trajectories import RunTrajectories
from safety.robot_model import RobotModel
from safety.trajectory import GripperEvent

if TYPE_CHECKING:
    from runtime.run.context import RunContext

log = logging.getLogger(__name__)

FILE = "run.rrd"
APPLICATION_ID = "goalvla"
TIMELINE = "run_time"
LINK_RATE_HZ = 50.0  # robot link poses are logged at this rate (the joint scalars at every tick)
CLOUD_POINTS_MAX = 60_000  # per cloud; the scene cloud is already voxelised
ENTITIES = {
    "capture": "images/capture",
    "goal": "images/goal",
    "overlay": "images/overlay",
    "masks": "images/masks",
    "after": "images/after",
    "camera": "world/camera",
    "camera_image": "world/camera/image",
    "scene_cloud": "world/scene_cloud",
    "target_initial": "world/target/initial",
    "target_goal": "world/target/goal",
    "object_motion": "world/target/motion",
    "pre_contact": "world/gripper/pre_contact",
    "contact": "world/gripper/contact",
    "gripper_goal": "world/gripper/goal",
    "via": "world/gripper/via",
    "robot": "world/robot",
    "tcp_planned": "world/tcp_path/planned",
    "tcp_executed": "world/tcp_path/executed",
    "joints_planned": "joints/planned",
    "joints_executed": "joints/executed",
    "tracking_error": "tracking_error_deg",
    "states": "timeline/states",
    "gate": "timeline/gate",
    "events": "timeline/events",
}
GREY, BLUE, GREEN, ORANGE = (170, 170, 170), (40, 90, 200), (30, 170, 60), (230, 120, 20)


def _time(rec: rr.RecordingStream, seconds: float) -> None:
    rec.set_time(TIMELINE, duration=max(0.0, float(seconds)))


def _log_pose(rec: rr.RecordingStream, path: str, T: np.ndarray, axis_length: float = 0.06, **kw) -> None:
    """A frame at T (base frame), drawn as its three axes."""
    rec.log(path, rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), rr.TransformAxes3D(axis_length), **kw)


def _subsample(points: np.ndarray, n: int) -> np.ndarray:
    return points if len(points) <= n else points[np.linspace(0, len(points) - 1, n).astype(int)]


def _stage_times(summary: RunSummary) -> tuple[float, dict[str, float]]:
    """(the run's start stamp, seconds from it at which each state was left, the last time it was left)."""
    if not summary.transitions:
        return 0.0, {}
    t0 = summary.transitions[0].stamp_s
    left = {t.previous: t.stamp_s - t0 for t in summary.transitions}
    return t0, left


def _log_images(rec: rr.RecordingStream, run_dir: Path, summary: RunSummary, left: dict[str, float]) -> None:
    """The run folder's PNGs, as written (no re-encoding), at the end of the stage that made them."""
    when = {"capture": "CAPTURING", "goal": "REASONING", "overlay": "REASONING", "masks": "REASONING"}
    for name in ("capture", "goal", "overlay", "masks", "after"):
        path = run_dir / f"{name}.png"
        if f"{name}.png" in summary.images and path.is_file():
            _time(rec, left.get(when.get(name, "VERIFYING"), 0.0))
            rec.log(ENTITIES[name], rr.EncodedImage(path=path))


def _log_camera(rec: rr.RecordingStream, ctx: RunContext, run_dir: Path) -> None:
    """The camera where the calibration puts it, seeing the capture (static: it does not move)."""
    frame = ctx.frame0
    if frame is None or frame.T_base_camera is None:
        return
    h, w = frame.rgb.shape[:2]
    _log_pose(rec, ENTITIES["camera"], frame.T_base_camera, 0.1, static=True)
    rec.log(
        ENTITIES["camera"],
        rr.Pinhole(image_from_camera=frame.intrinsics.K, resolution=[w, h], image_plane_distance=0.15),
        static=True,
    )
    if (run_dir / "capture.png").is_file():
        rec.log(ENTITIES["camera_image"], rr.EncodedImage(path=run_dir / "capture.png"), static=True)


def _log_clouds(rec: rr.RecordingStream, ctx: RunContext, left: dict[str, float]) -> None:
    clouds = ctx.clouds
    if clouds is None:
        return
    _time(rec, left.get("PLANNING", 0.0))
    scene = _subsample(clouds.scene, CLOUD_POINTS_MAX)
    target = _subsample(clouds.target, CLOUD_POINTS_MAX)
    rec.log(ENTITIES["scene_cloud"], rr.Points3D(scene, colors=GREY, radii=0.003))
    rec.log(ENTITIES["target_initial"], rr.Points3D(target, colors=BLUE, radii=0.003))
    T = ctx.contact.T_motion if ctx.contact is not None else (ctx.motion.T_base if ctx.motion is not None else None)
    if T is not None and len(target):
        goal = target @ T[:3, :3].T + T[:3, 3]
        rec.log(ENTITIES["target_goal"], rr.Points3D(goal, colors=GREEN, radii=0.003))
        centre = target.mean(axis=0)
        moved = T[:3, :3] @ centre + T[:3, 3]
        rec.log(ENTITIES["object_motion"], rr.Arrows3D(origins=[centre], vectors=[moved - centre], colors=ORANGE))


def _log_contact(rec: rr.RecordingStream, ctx: RunContext, left: dict[str, float]) -> None:
    c = ctx.contact
    if c is None:
        return
    _time(rec, left.get("PLANNING", 0.0))
    _log_pose(rec, ENTITIES["pre_contact"], c.T_pre)
    _log_pose(rec, ENTITIES["contact"], c.T_contact)
    _log_pose(rec, ENTITIES["gripper_goal"], c.T_goal)
    extra = [*c.via, *c.T_place]
    if extra:
        rec.log(ENTITIES["via"], rr.Points3D([T[:3, 3] for T in extra], colors=ORANGE, radii=0.006))


def _quat_xyzw(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_quat()


def _log_robot_geometry(rec: rr.RecordingStream, robot: RobotModel) -> None:
    """Each link's collision shapes from the description (the URDF's source), in the link's frame (static)."""
    spec = robot.spec
    shapes = {name: link.collision for name, link in spec.links.items()}
    for finger in spec.gripper.finger_links:
        shapes[finger] = spec.gripper.finger_collision
    for link, collision in shapes.items():
        for i, shape in enumerate(collision):
            path = f"{ENTITIES['robot']}/{link}/shape_{i}"
            if isinstance(shape, Capsule):  # Rerun's capsule runs along +z from its translation
                archetype = rr.Capsules3D(
                    lengths=[shape.length],
                    radii=[shape.radius],
                    translations=[shape.p0],
                    quaternions=[_quat_xyzw(shape.rotation())],
                    colors=GREY,
                )
            elif isinstance(shape, Cylinder):
                archetype = rr.Cylinders3D(
                    lengths=[shape.length], radii=[shape.radius], centers=[shape.xyz], colors=GREY
                )
            elif isinstance(shape, Box):
                archetype = rr.Boxes3D(sizes=[shape.size], centers=[shape.xyz], colors=GREY, fill_mode="solid")
            else:
                continue
            rec.log(path, archetype, static=True)


def _log_link_poses(
    rec: rr.RecordingStream, robot: RobotModel, times: np.ndarray, q: np.ndarray, widths: np.ndarray
) -> None:
    """Every link's pose at each of `times` [s], by forward kinematics of q (N, dof) with the finger gaps."""
    poses = [robot.fk(qk, wk) for qk, wk in zip(q, widths, strict=True)]
    for link in robot.link_names:
        T = np.array([p[link] for p in poses])
        rec.send_columns(
            f"{ENTITIES['robot']}/{link}",
            indexes=[rr.TimeColumn(TIMELINE, duration=times)],
            columns=rr.Transform3D.columns(translation=T[:, :3, 3], mat3x3=T[:, :3, :3]),
        )


def _finger_gaps(events: tuple[GripperEvent, ...], tau_s: np.ndarray, gap_m: float) -> tuple[np.ndarray, float]:
    """The commanded finger gap at each trajectory time (a step at each open/close), and the gap after them."""
    gaps = np.full(len(tau_s), gap_m)
    for event in sorted(events, key=lambda e: e.time_s):
        if event.kind in ("open", "close"):
            gaps[tau_s >= event.time_s] = event.width_m
            gap_m = event.width_m
    return gaps, gap_m


def _scalars(rec: rr.RecordingStream, path: str, times: np.ndarray, values: np.ndarray) -> None:
    rec.send_columns(
        path, indexes=[rr.TimeColumn(TIMELINE, duration=times)], columns=rr.Scalars.columns(scalars=values)
    )


def _log_trajectories(
    rec: rr.RecordingStream, ctx: RunContext, traj: RunTrajectories, robot: RobotModel, left: dict[str, float]
) -> None:
    """Planned and executed joints on the timeline (executed where they were streamed, planned aligned with
    them), the robot following the measured joints, both TCP paths, and the gate's verdict on each phase."""
    motion_start = left.get("AWAITING_CONFIRM", left.get("PLANNING", 0.0))
    executed = {e.name: e for e in traj.executed}
    events = {}
    if ctx.manipulation is not None:
        events = {
            name: a.trajectory.gripper_events
            for name, a in zip(ctx.manipulation.phase_names, ctx.manipulation.phases, strict=True)
        }
    t, planned_tcp = motion_start, []
    for p in traj.planned:
        start = motion_start + executed[p.name].start_s if p.name in executed else t
        times = start + p.times
        for j, name in enumerate(traj.joint_names):
            _scalars(rec, f"{ENTITIES['joints_planned']}/{name}", times, p.positions[:, j])
        planned_tcp.append(robot.tcp_positions(p.positions[:: max(1, len(p.positions) // 200)]))
        t = times[-1] + p.dt
        _time(rec, start)
        verdict = "passed" if p.gate_ok else "REFUSED"
        text = f"{p.name}: gate {verdict} ({p.gate_samples} samples, {p.gate_configurations} configurations checked)"
        rec.log(ENTITIES["gate"], rr.TextLog(text, level="INFO" if p.gate_ok else "ERROR"))
    if planned_tcp:
        _time(rec, left.get("PLANNING", 0.0))
        rec.log(ENTITIES["tcp_planned"], rr.LineStrips3D([np.vstack(planned_tcp)], colors=BLUE, radii=0.002))
    gap = robot.spec.gripper.max_width_m
    link_times, link_q, link_gaps = [], [], []
    for e in traj.executed:
        if not len(e.times_s):
            continue
        times = motion_start + e.start_s + e.times_s
        for j, name in enumerate(traj.joint_names):
            _scalars(rec, f"{ENTITIES['joints_executed']}/{name}", times, e.q_meas[:, j])
        _scalars(
            rec, ENTITIES["tracking_error"], times, np.degrees(e.tracking_error_rad(ExecutorConfig.tracking_lag_s))
        )
        gaps, gap = _finger_gaps(events.get(e.name, ()), e.tau_s, gap)
        period = float(np.median(np.diff(e.times_s))) if len(e.times_s) > 1 else 1.0 / LINK_RATE_HZ
        step = max(1, round(1.0 / (LINK_RATE_HZ * period)))
        link_times.append(times[::step])
        link_q.append(e.q_meas[::step])
        link_gaps.append(gaps[::step])
    if link_times:
        all_q = np.vstack(link_q)
        _log_link_poses(rec, robot, np.concatenate(link_times), all_q, np.concatenate(link_gaps))
        _time(rec, link_times[-1][-1])
        rec.log(ENTITIES["tcp_executed"], rr.LineStrips3D([robot.tcp_positions(all_q)], colors=GREEN, radii=0.002))


def _log_gripper_events(rec: rr.RecordingStream, summary: RunSummary, left: dict[str, float]) -> None:
    _time(rec, left.get("EXECUTING", 0.0))
    for phase in summary.execution:
        for g in phase.gripper:
            width = "" if g.width_m is None else f" at {1000 * g.width_m:.0f} mm"
            grasped = "" if g.grasped is None else (": grasped" if g.grasped else ": closed on nothing")
            rec.log(ENTITIES["events"], rr.TextLog(f"{phase.phase}: gripper {g.kind}{width}{grasped}"))


def blueprint() -> rrb.Blueprint:
    """The viewer's first layout: the 3D scene beside the pictures, the joints and the timeline's text."""
    images = [rrb.Spatial2DView(origin=ENTITIES[n], name=n) for n in ("capture", "goal", "overlay", "masks")]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                origin="world",
                name="scene (base frame)",
                eye_controls=rrb.EyeControls3D(
                    position=(1.25, -0.95, 0.85), look_target=(0.4, 0.0, 0.1), eye_up=(0, 0, 1)
                ),
            ),
            rrb.Vertical(
                rrb.Grid(*images),
                rrb.TimeSeriesView(origin="joints", name="joints [rad]: planned and executed"),
                rrb.TextLogView(origin="timeline", name="states, gate, gripper"),
                row_shares=[2, 2, 1],
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def write_recording(ctx: RunContext, summary: RunSummary, traj: RunTrajectories | None, run_dir: Path) -> Path:
    """Write run_dir/run.rrd from the ended run (its context, summary and trajectories); returns its path."""
    path = run_dir / FILE
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=summary.run_id)
    rec.save(path)
    try:
        rec.send_recording_name(f"{summary.run_id}: {summary.instruction}")
        rec.send_blueprint(blueprint())
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        t0, left = _stage_times(summary)
        for tr in summary.transitions:
            _time(rec, tr.stamp_s - t0)
            level = "ERROR" if tr.state in ("FAILED", "ESTOPPED") else "INFO"
            rec.log(ENTITIES["states"], rr.TextLog(f"{tr.previous} -> {tr.state}: {tr.reason}", level=level))
        _log_images(rec, run_dir, summary, left)
        _log_camera(rec, ctx, run_dir)
        _log_clouds(rec, ctx, left)
        _log_contact(rec, ctx, left)
        robot = RobotModel()
        _log_robot_geometry(rec, robot)
        q0 = traj.planned[0].positions[:1] if traj is not None and traj.planned else robot.home_q[None]
        _log_link_poses(rec, robot, np.zeros(1), q0, np.full(1, robot.spec.gripper.max_width_m))
        if traj is not None:
            _log_trajectories(rec, ctx, traj, robot, left)
        _log_gripper_events(rec, summary, left)
    finally:
        rec.flush()
        rec.disconnect()
    return path
