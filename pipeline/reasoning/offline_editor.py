"""Offline image editor: composes the goal image from the current RGB-D view for an instruction in the grammar.

The target's pixels are lifted to 3D with the measured depth and intrinsics, moved rigidly to where the
instruction puts them (found from the segmented reference object and the table plane: beside a reference, the
first free, supported spot in reach and in view around the relation's direction, see placement.py; a push's or
a placement's goal that is none of these is refused with the reason), projected back with a
z-buffer (correct perspective scale and occlusion) and splatted; the vacated region is inpainted (cv2.inpaint).
For "stand up" the hidden underside turns into view, so the lying body is first completed as a solid of revolution.
For "close" only the object's lid moves: it turns about the line where it meets the box (the hinge grounding
also finds) until it lies flat over the box.
The goal's depth is composed the same way and handed over as normalised disparity (like a relative monocular
model), together with the applied rigid motion, which is the ground truth a benchmark compares grounding to.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy.ndimage import distance_transform_edt, median_filter

from drivers.types import CameraIntrinsics
from pipeline.grounding.articulation import HingeNotFound, find_hinge
from pipeline.perception.depth import OfflineDepthEstimator, RelativeDepth
from pipeline.perception.segmenter import SegmentationError, Segmenter, apart_from, matches
from pipeline.reasoning.checks import grow
from pipeline.reasoning.instruction import Instruction, InstructionError, lid_of, parse_instruction
from pipeline.reasoning.interfaces import ImageEditor
from pipeline.reasoning.placement import PlacementConfig, Table, spot_beside
from pipeline.reasoning.providers import ProviderError
from pipeline.reasoning.tabletop import (
    Footprint,
    GeometryError,
    Plane,
    axis_rotation,
    fit_table_plane,
    footprint,
    object_points,
    principal_axis,
    rim_centre,
    support_height,
    top_centre,
    wide_end,
)
from pipeline.reasoning.types import EditRequest, EditResult

FIT_MARGIN = 1.1  # an object put on or in another may be this much wider than it (its seen footprint is partial)
# an object put on or in another is released this far above the support: clear of contact planning's 4 mm
# placed-object check, so a measured millimetre of grounding error does not read as the object sinking into it
RELEASE_ABOVE_M = 0.006
MIN_VISIBLE_FRACTION = 0.3
# an object whose lowest visible point is this close to the table rests on it: its underside is hidden (a ball's
# lower half, a block's near edge in shadow), so its bottom is the table, not the lowest point seen
RESTING_M = 0.03


def _refuse(message: str) -> ProviderError:
    return ProviderError("refused", f"offline editor: {message}", raw=message)


def _single(segmenter: Segmenter, rgb: np.ndarray, phrase: str, other_than: np.ndarray | None = None) -> np.ndarray:
    """The one object the phrase names (not the object of `other_than`: a reference is not its target)."""
    try:
        found = segmenter.segment(rgb, phrase)
    except SegmentationError as e:
        raise _refuse(str(e)) from None
    if other_than is not None:
        found = apart_from(found, other_than)
    if len(found) != 1:
        raise _refuse(f"'{phrase}' {matches(found)} in the current image (needs exactly one)")
    return found[0].mask


class OfflineEditor(ImageEditor):
    name = "offline"

    def __init__(
        self,
        segmenter: Segmenter,
        depth_registry: OfflineDepthEstimator | None = None,
        placement: PlacementConfig | None = None,
    ) -> None:
        self.segmenter = segmenter
        self.depth_registry = depth_registry
        self.placement = placement or PlacementConfig()

    def edit(self, request: EditRequest) -> EditResult:
        if request.depth_m is None or request.intrinsics is None:
            raise _refuse("needs the current depth frame and intrinsics")
        try:
            instr = parse_instruction(request.prompt)
        except InstructionError as e:
            raise _refuse(str(e)) from None
        try:
            rgb, depth_m, T = self._compose(request, instr)
        except GeometryError as e:
            raise _refuse(str(e)) from None
        disparity = 1.0 / depth_m
        lo, hi = float(np.nanmin(disparity)), float(np.nanmax(disparity))
        rel = RelativeDepth(((disparity - lo) / max(hi - lo, 1e-9)).astype(np.float32), "disparity")
        if self.depth_registry is not None:
            self.depth_registry.remember(rgb, rel)
        return EditResult(rgb, raw=f"composed: {instr.canonical()}", relative_depth=rel, T_goal_init_camera=T)

    def _compose(self, request: EditRequest, instr: Instruction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rgb, depth_m, K = request.rgb, request.depth_m, request.intrinsics
        if instr.action == "close":
            return self._close(rgb, depth_m, K, instr.target)
        mask_x = _single(self.segmenter, rgb, instr.target)
        cloud = K.unproject_depth_image(depth_m)[::3, ::3].reshape(-1, 3)
        plane = fit_table_plane(cloud)
        px, _ = object_points(depth_m, K, mask_x)
        fx = footprint(px, plane)
        fy, exclude = None, grow(mask_x, 3)
        if instr.reference is not None:
            mask_y = _single(self.segmenter, rgb, instr.reference, other_than=mask_x)
            py, _ = object_points(depth_m, K, mask_y)
            fy = footprint(py, plane)
            if instr.relation in ("on", "in"):  # the reference is where it goes, not in its way
                exclude |= grow(mask_y, 3)
        table = Table(depth_m, K, plane, exclude, request.T_base_camera, self.placement)
        R, pivot, t = self._motion(instr, plane, fx, fy, table)
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = pivot - R @ pivot + t
        colours = rgb[mask_x]
        if instr.action == "stand_up":  # the hidden underside turns into view: complete the body first
            px, colours = revolve(fx, colours, plane)
        goal_rgb, goal_depth = _render(rgb, depth_m, K, plane, mask_x, px, colours, T)
        return goal_rgb, goal_depth, T

    def _close(
        self, rgb: np.ndarray, depth_m: np.ndarray, K: CameraIntrinsics, phrase: str
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The lid turned about its hinge until it lies over the box, pointing from the hinge to the box's centre."""
        mask_lid = _single(self.segmenter, rgb, lid_of(phrase))
        mask_box = _single(self.segmenter, rgb, phrase) & ~mask_lid
        cloud = K.unproject_depth_image(depth_m)[::3, ::3].reshape(-1, 3)
        plane = fit_table_plane(cloud)
        lid, _ = object_points(depth_m, K, mask_lid)
        box, _ = object_points(depth_m, K, mask_box)
        try:
            hinge = find_hinge(lid, box)
        except HingeNotFound as e:
            raise _refuse(f"'{phrase}': {e}") from e
        closed = plane.in_plane(footprint(box, plane).centre - hinge.point)  # from the hinge over the box
        closed -= (closed @ hinge.axis) * hinge.axis
        now = lid.mean(axis=0) - hinge.point
        now -= (now @ hinge.axis) * hinge.axis
        if np.linalg.norm(closed) < 1e-3 or np.linalg.norm(now) < 1e-3:
            raise _refuse(f"'{phrase}': the lid does not reach away from its hinge, or the box lies on the hinge line")
        angle = math.atan2(float(np.cross(now, closed) @ hinge.axis), float(now @ closed))
        T = hinge.turn(angle).matrix
        goal_rgb, goal_depth = _render(rgb, depth_m, K, plane, mask_lid, lid, rgb[mask_lid], T, keep=mask_box)
        return goal_rgb, goal_depth, T

    @staticmethod
    def _motion(
        instr: Instruction, plane: Plane, fx: Footprint, fy: Footprint | None, table: Table
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rotation, pivot and translation (camera frame) that carry out the instruction."""
        right = plane.in_plane(np.array([1.0, 0.0, 0.0]))
        away = plane.in_plane(np.array([0.0, 0.0, 1.0]))
        eye, zero = np.eye(3), np.zeros(3)
        bottom = float(np.percentile(fx.heights, 2))
        bottom = 0.0 if bottom < RESTING_M else bottom
        if instr.action == "place":
            where = f"{instr.relation.replace('_', ' ')} the {instr.reference}"
            if instr.relation in ("on", "in"):
                if fx.radius_m > FIT_MARGIN * fy.radius_m:
                    raise GeometryError(
                        f"the {instr.target} ({fx.radius_m * 1000:.0f} mm across its middle) does not fit {where} "
                        f"({fy.radius_m * 1000:.0f} mm)"
                    )
                # the middles of the tops (a container's by its rim): the seen points' middle leans to the camera
                there = rim_centre(fy, plane) if instr.relation == "in" else top_centre(fy, plane)
                lift = support_height(fy, plane, there) - bottom + RELEASE_ABOVE_M
                shift = there - top_centre(fx, plane) + lift * plane.n
                problem = table.problem(fx, shift, hidden_ok=instr.relation == "in")  # walls may hide it
                if problem is not None:
                    raise GeometryError(f"cannot put the {instr.target} {where}: {problem}")
                return eye, zero, shift
            side = {
                "left_of": -right,
                "right_of": right,
                "behind": away,
                "in_front_of": -away,
            }.get(instr.relation)
            if side is None:  # next to: stay on the side the object is already on
                offset = fx.centre - fy.centre
                side = plane.in_plane(offset) if np.linalg.norm(offset) > 1e-3 else right
            shift, why = spot_beside(table, fx, fy, side, where)
            if shift is None:
                raise GeometryError(why)
            return eye, zero, shift
        if instr.action == "rotate":
            return axis_rotation(plane.n, math.radians(instr.angle_deg)), top_centre(fx, plane), zero
        if instr.action == "push":
            direction = {"left": -right, "right": right, "away": away, "toward": -away}[instr.direction]
            problem = table.problem(fx, direction * instr.distance_m)
            if problem is not None:
                raise GeometryError(f"cannot {instr.canonical()}: where it would end is {problem}")
            return eye, zero, direction * instr.distance_m
        # stand up: turn the long axis vertical with the wider end (a bottle's base, not its neck) down; a body with
        # equal ends keeps its visible side facing the camera. +90 deg about n x axis takes the +axis end down.
        axis = principal_axis(fx, plane)
        tilt_axis = np.cross(plane.n, axis)
        pivot = fx.points.mean(axis=0)
        sign = wide_end(fx, plane, axis)
        R = axis_rotation(tilt_axis, math.pi / 2 if sign >= 0 else -math.pi / 2)
        if sign == 0 and (R @ plane.n) @ -pivot < 0:
            R = axis_rotation(tilt_axis, -math.pi / 2)
        lowest = plane.height((fx.points - pivot) @ R.T + pivot).min()
        return R, pivot, -lowest * plane.n


def _render(
    rgb: np.ndarray,
    depth_m: np.ndarray,
    K: CameraIntrinsics,
    plane: Plane,
    mask_x: np.ndarray,
    points: np.ndarray,
    colours: np.ndarray,
    T: np.ndarray,
    keep: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Goal RGB and metric depth: inpaint where the object was, then z-buffer splat it at its new pose.

    `keep`: pixels that stay as they are and must not bleed into the vacated region (a lid's box)."""
    h, w = mask_x.shape
    vacated = grow(mask_x, 3)
    hole = vacated if keep is None else vacated | keep
    goal = cv2.inpaint(rgb, hole.astype(np.uint8) * 255, 5, cv2.INPAINT_TELEA)
    if keep is not None:
        goal[keep & ~vacated] = rgb[keep & ~vacated]
    depth = depth_m.astype(np.float64).copy()
    vv, vu = np.nonzero(vacated)
    depth[vv, vu] = plane.ray_depth(K, np.stack([vu, vv], axis=1).astype(np.float64))
    invalid = ~np.isfinite(depth)
    if invalid.any():
        _, (iv, iu) = distance_transform_edt(invalid, return_indices=True)
        depth = depth[iv, iu]

    moved = points @ T[:3, :3].T + T[:3, 3]
    front = moved[:, 2] > 1e-3
    uv = np.full((len(moved), 2), -1.0)
    uv[front] = K.project(moved[front])
    u, v = np.round(uv[:, 0]).astype(int), np.round(uv[:, 1]).astype(int)
    inside = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    if inside.sum() < MIN_VISIBLE_FRACTION * len(moved):
        raise GeometryError(f"the goal pose leaves the camera view ({inside.sum()} of {len(moved)} pixels in view)")
    u, v, z, colours = u[inside], v[inside], moved[inside, 2], colours[inside]
    order = np.lexsort((z, v * w + u))  # nearest point first within each pixel
    flat = (v * w + u)[order]
    first = np.r_[True, flat[1:] != flat[:-1]]
    keep = order[first]
    u, v, z, colours = u[keep], v[keep], z[keep], colours[keep]
    seen = z < depth[v, u] + 0.003  # scene surfaces nearer than the moved object occlude it
    splat = np.zeros((h, w), bool)
    splat[v[seen], u[seen]] = True
    zbuf = np.zeros((h, w))
    zbuf[v[seen], u[seen]] = z[seen]
    cbuf = np.zeros_like(rgb)
    cbuf[v[seen], u[seen]] = colours[seen]
    scale = float(np.median(points[inside][keep][:, 2] / z)) if len(points) == mask_x.sum() else 1.0
    k = 2 * math.ceil(max(scale, 1.0)) + 1
    closed = cv2.morphologyEx(splat.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((k, k), np.uint8)).astype(bool)
    _, (iv, iu) = distance_transform_edt(~splat, return_indices=True)  # holes take the nearest splatted pixel
    goal[closed] = cbuf[iv, iu][closed]
    depth[closed] = np.minimum(zbuf[iv, iu][closed], depth[closed])
    return goal, depth.astype(np.float32)


def revolve(fp: Footprint, colours: np.ndarray, plane: Plane, step_m: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
    """A lying body completed as a solid of revolution about its long axis, from its visible (upper) surface.

    The body rests on the table, so its axis lies one body radius above it: the cross-section circle (axis
    position across and radius) is fitted, under that constraint, to the seen points of the widest slices (the
    body, not a bottle's neck; the seen arc is one-sided, so its middle is not the axis). Each slice along the axis
    takes its own radius about that axis and the median colour seen in it. Used for stand-up, where the hidden
    underside turns towards the camera.
    """
    axis = principal_axis(fp, plane)
    across = np.cross(plane.n, axis)
    q = plane.project(fp.points) - fp.centre
    s, w, h = q @ axis, q @ across, fp.heights
    bins = np.arange(s.min(), s.max() + step_m, step_m)
    idx = np.clip(np.digitize(s, bins) - 1, 0, len(bins) - 1)
    slice_width = np.zeros(len(bins))
    for k in np.unique(idx):
        slice_width[k] = np.ptp(np.percentile(w[idx == k], [5, 95]))
    body = slice_width[idx] >= 0.8 * np.percentile(slice_width[slice_width > 0], 90)
    # the circle touching the table through the body's seen points: w^2 + h^2 = 2 a w + 2 r h - a^2
    A = np.column_stack([2 * w[body], 2 * h[body], -np.ones(body.sum())])
    (centre_across, body_radius, _), *_ = np.linalg.lstsq(A, w[body] ** 2 + h[body] ** 2)
    if not 0.0 < body_radius < 2 * fp.radius_m:
        raise GeometryError(f"no lying body of revolution fits the target (fitted radius {body_radius * 1000:.0f} mm)")
    distance = np.hypot(w - centre_across, h - body_radius)  # of each seen point from the fitted axis
    radius_profile = np.zeros(len(bins))
    slice_colour = np.tile(np.median(colours, axis=0), (len(bins), 1))
    for k in np.unique(idx):
        sel = idx == k
        radius_profile[k] = min(np.median(distance[sel]), body_radius)
        slice_colour[k] = np.median(colours[sel], axis=0)
    seen = np.unique(idx)  # slices without a seen point take their neighbours' radius, not the body's
    radius_profile = np.interp(np.arange(len(bins)), seen, radius_profile[seen])
    radius_profile = median_filter(radius_profile, size=5, mode="nearest")  # a few stray edge points per slice
    origin = fp.centre + centre_across * across + body_radius * plane.n
    pts, cols = [], []
    for k, s_k in enumerate(bins):
        r = radius_profile[k]
        n_around = max(8, int(2 * np.pi * r / step_m))
        theta = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
        ring = origin + s_k * axis + r * (np.cos(theta)[:, None] * across + np.sin(theta)[:, None] * plane.n)
        pts.append(ring)
        cols.append(np.tile(slice_colour[k], (len(ring), 1)))
        if k in (0, len(bins) - 1):  # end caps
            for rr in np.arange(step_m, r, step_m):
                m = max(6, int(2 * np.pi * rr / step_m))
                th = np.linspace(0.0, 2 * np.pi, m, endpoint=False)
                pts.append(origin + s_k * axis + rr * (np.cos(th)[:, None] * across + np.sin(th)[:, None] * plane.n))
                cols.append(np.tile(slice_colour[k], (m, 1)))
    return np.concatenate(pts), np.concatenate(cols).astype(np.uint8)
