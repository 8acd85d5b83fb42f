"""Offline image editor: composes the goal image from the current RGB-D view for an instruction in the grammar.

The target's pixels are lifted to 3D with the measured depth and intrinsics, moved rigidly to where the
instruction puts them (found from the segmented reference object and the table plane: beside a reference, the
first free, supported spot in reach and in view around the relation's direction, see placement.py; a push's or
a placement's goal that is none of these is refused with the reason), projected back with a
z-buffer (correct perspective scale and occlusion) and splatted; the vacated region is inpainted (cv2.inpaint).
For "stand up" the hidden underside turns into view, so the lying body is first completed as a solid of revolution.
For "close" only the object's lid moves: it turns about the line where it meets the box (the hinge grounding
also finds) until it lies flat over the box. "Lift" raises the object straight up. "Take X off Y" sets X down on
the table at the first free spot beside Y (in front, then to the sides, then behind), laid on its face when it
stood on its rim (a plate in a rack). "Sweep X into Y" moves every instance of X into the container Y: the group
keeps its layout, drawn together about the container floor's centre as far as needed to fit on it.
The goal's depth is composed the same way and handed over as normalised disparity (like a relative monocular
model), together with the applied rigid motion, which is the ground truth a benchmark compares grounding to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import distance_transform_edt, median_filter
from scipy.spatial import ConvexHull

from drivers.types import CameraIntrinsics
from pipeline.grounding.articulation import HingeNotFound, find_hinge
from pipeline.perception.depth import OfflineDepthEstimator, RelativeDepth
from pipeline.perception.segmenter import SegmentationError, Segmenter, apart_from, attached_to, grow, matches
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


def _single(
    segmenter: Segmenter,
    rgb: np.ndarray,
    depth_m: np.ndarray,
    phrase: str,
    other_than: np.ndarray | None = None,
    part: np.ndarray | None = None,
) -> np.ndarray:
    """The one object the phrase names (not the object of `other_than`: a reference is not its target; of several,
    the one `part` is attached to: a lid's chest)."""
    try:
        found = segmenter.segment(rgb, phrase, depth_m)
    except SegmentationError as e:
        raise _refuse(str(e)) from None
    if other_than is not None:
        found = apart_from(found, other_than)
    if part is not None:
        found = attached_to(found, part)
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
        if instr.action == "sweep":
            return self._sweep(request, instr)
        mask_x = _single(self.segmenter, rgb, depth_m, instr.target)
        cloud = K.unproject_depth_image(depth_m)[::3, ::3].reshape(-1, 3)
        plane = fit_table_plane(cloud)
        px, _ = object_points(depth_m, K, mask_x)
        fx = footprint(px, plane)
        fy, exclude = None, grow(mask_x, 3)
        if instr.reference is not None:
            mask_y = _single(self.segmenter, rgb, depth_m, instr.reference, other_than=mask_x)
            py, _ = object_points(depth_m, K, mask_y)
            fy = footprint(py, plane)
            if instr.relation in ("on", "in"):  # the reference is where it goes, not in its way
                exclude |= grow(mask_y, 3)
            if instr.action == "take_off":  # X stands on Y: pixels of X whose depth is Y's (its edge) are Y's
                keep = ~_on_support(px, plane, py)
                mask_x = mask_x.copy()
                mask_x[mask_x] = keep
                px = px[keep]
                fx = footprint(px, plane)
        table = Table(depth_m, K, plane, exclude, request.T_base_camera, self.placement)
        R, pivot, t = self._motion(instr, plane, fx, fy, table)
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = pivot - R @ pivot + t
        colours = rgb[mask_x]
        if instr.action == "stand_up":  # the hidden underside turns into view: complete the body first
            px, colours = revolve(fx, colours, plane)
        elif instr.action == "take_off" and not np.allclose(R, np.eye(3)):  # a face turned towards the camera
            px, colours = _subsampled(px, colours)  # shows more of it than its pixels covered
        goal_rgb, goal_depth = _render(rgb, depth_m, K, plane, mask_x, px, colours, T)
        return goal_rgb, goal_depth, T

    def _close(
        self, rgb: np.ndarray, depth_m: np.ndarray, K: CameraIntrinsics, phrase: str
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The lid turned about its hinge until it lies over the box, pointing from the hinge to the box's centre."""
        mask_lid = _single(self.segmenter, rgb, depth_m, lid_of(phrase))
        mask_box = _single(self.segmenter, rgb, depth_m, phrase, part=mask_lid) & ~mask_lid
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

    def _sweep(self, request: EditRequest, instr: Instruction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every instance of the target moved onto the container's floor, the group's layout kept and drawn
        together about the floor's centre as far as it needs to fit; T is the group centroid's motion."""
        rgb, depth_m, K = request.rgb, request.depth_m, request.intrinsics
        try:
            found = self.segmenter.segment(rgb, instr.target, depth_m)
        except SegmentationError as e:
            raise _refuse(str(e)) from None
        if not found:
            raise _refuse(f"'{instr.target}' matches no object in the current image")
        mask_y = _single(self.segmenter, rgb, depth_m, instr.reference)
        plane = fit_table_plane(K.unproject_depth_image(depth_m)[::3, ::3].reshape(-1, 3))
        floor = container_floor(object_points(depth_m, K, mask_y)[0], plane)
        parts = [object_points(depth_m, K, d.mask)[0] for d in found]
        centres = np.array([footprint(pts, plane).centre for pts in parts])
        # a part's centre keeps half its reach from the floor's edge: a long part may lie along it
        radius = 0.5 * max(footprint(pts, plane).radius_m for pts in parts)
        group_centre = centres.mean(axis=0)
        for s in (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.0):  # drawn together no more than it must
            goals = floor.centre + s * (centres - group_centre)
            if floor.holds(goals, radius):
                break
        else:
            raise GeometryError(
                f"the {instr.target} do not fit on the {instr.reference}'s floor (parts {4 * radius * 1000:.0f} mm "
                f"long, floor {floor.size_m * 1000:.0f} mm across)"
            )
        shifts = goals - centres + floor.height_m * plane.n
        moved = np.concatenate([pts + shift for pts, shift in zip(parts, shifts, strict=True)])
        mask_x = np.any([d.mask for d in found], axis=0)
        colours = np.concatenate([rgb[d.mask & np.isfinite(depth_m)] for d in found])
        goal_rgb, goal_depth = _render(rgb, depth_m, K, plane, mask_x, moved, colours, np.eye(4))
        T = np.eye(4)
        T[:3, 3] = floor.centre - group_centre + floor.height_m * plane.n
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
                lift = support_height(fy, plane, there, container=instr.relation == "in") - bottom + RELEASE_ABOVE_M
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
        if instr.action == "lift":
            shift = instr.distance_m * plane.n
            problem = table.problem(fx, shift)
            if problem is not None:
                raise GeometryError(f"cannot {instr.canonical()}: up there it would be {problem}")
            return eye, zero, shift
        if instr.action == "take_off":
            return _take_off(instr, plane, fx, fy, table)
        if instr.action == "push":
            direction = {"left": -right, "right": right, "away": away, "toward": -away}[instr.direction]
            problem = table.problem(fx, direction * instr.distance_m, pushed=True)
            if problem is not None:
                raise GeometryError(f"cannot {instr.canonical()}: where it would end is {problem}")
            blocked = table.in_the_way(fx, direction * instr.distance_m)
            if blocked is not None:
                raise GeometryError(f"cannot {instr.canonical()}: {blocked}")
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


FLOOR_BAND_M = 0.006  # a container's points this close above its lowest are its floor
FLOOR_MARGIN_M = 0.008  # kept between a part put on a floor and the floor's seen edge


@dataclass(frozen=True)
class Floor:
    """A container's floor seen from the camera: its points' convex outline on the table plane."""

    plane: Plane
    hull: ConvexHull  # of the floor points in plane coordinates (e1, e2)
    e1: np.ndarray
    e2: np.ndarray
    centre: np.ndarray  # camera frame, on the table plane
    height_m: float  # above the table

    @property
    def size_m(self) -> float:
        """Twice the distance from the centre to the nearest edge of the floor."""
        return float(2 * np.min(-self.hull.equations[:, 2]))

    def holds(self, centres: np.ndarray, radius_m: float) -> bool:
        """Whether discs of radius_m at these centres (camera frame) lie inside the floor, with a margin (the
        hull's coordinates have the floor's centre at their origin)."""
        q = np.stack([(centres - self.centre) @ self.e1, (centres - self.centre) @ self.e2], axis=1)
        eq = self.hull.equations
        return bool((q @ eq[:, :2].T + eq[:, 2] <= -(radius_m + FLOOR_MARGIN_M)).all())


def container_floor(points: np.ndarray, plane: Plane) -> Floor:
    """The floor of a low container (a dustpan): its points lying within FLOOR_BAND_M of its lowest."""
    if len(points) < 20:
        raise GeometryError(f"the container shows only {len(points)} points with depth")
    h = plane.height(points)
    low = points[h < np.percentile(h, 3) + FLOOR_BAND_M]
    if len(low) < 20:
        raise GeometryError("the container shows no floor")
    centre = plane.project(low.mean(axis=0))
    e1 = plane.in_plane(np.array([1.0, 0.0, 0.0]))
    e2 = np.cross(plane.n, e1)
    q = np.stack([(low - centre) @ e1, (low - centre) @ e2], axis=1)
    return Floor(plane, ConvexHull(q), e1, e2, centre, float(np.median(plane.height(low))))


TAKE_OFF_SIDES = ("in_front_of", "right_of", "left_of", "behind")  # where a taken-off object goes, in order
ON_EDGE_RATIO = 0.35  # an object whose thinnest extent is horizontal and below this share of the next stands on edge


def _on_support(points: np.ndarray, plane: Plane, support: np.ndarray) -> np.ndarray:
    """Which of an object's points are its support's (depth bleeding across the edge): within 5 mm of them."""
    from scipy.spatial import cKDTree

    if len(support) == 0:
        return np.zeros(len(points), bool)
    d, _ = cKDTree(support).query(points, distance_upper_bound=0.005)
    return np.isfinite(d)


def _take_off(
    instr: Instruction, plane: Plane, fx: Footprint, fy: Footprint, table: Table
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """X off its support Y, set down on the table beside Y: the first free spot in front of Y, to its sides or
    behind it; an object standing on edge (a plate in a rack) is laid on its face, the face the camera sees up."""
    right = plane.in_plane(np.array([1.0, 0.0, 0.0]))
    away = plane.in_plane(np.array([0.0, 0.0, 1.0]))
    sides = {"left_of": -right, "right_of": right, "behind": away, "in_front_of": -away}
    R, pivot = np.eye(3), fx.points.mean(axis=0)
    thin = _thin_axis(fx.points)
    if thin is not None and abs(thin @ plane.n) < 0.5:  # on edge: its face turns up
        face = thin if thin @ -pivot > 0 else -thin  # the seen side faces the camera (at the origin)
        axis = np.cross(face, plane.n)
        angle = math.acos(float(np.clip(face @ plane.n, -1.0, 1.0)))
        R = axis_rotation(axis, angle)
    turned = (fx.points - pivot) @ R.T + pivot
    lowest = float(plane.height(turned).min())
    moved = footprint(turned, plane)
    problems = []
    for side in TAKE_OFF_SIDES:
        where = f"{side.replace('_', ' ')} the {instr.reference}"
        shift, why = spot_beside(table, moved, fy, sides[side], where)
        if shift is not None:  # measured from the turned footprint: R about the pivot, then the shift, down
            return R, pivot, shift - lowest * plane.n
        problems.append(why)
    raise GeometryError(f"cannot {instr.canonical()}: " + "; ".join(problems))


def _subsampled(points: np.ndarray, colours: np.ndarray, k: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """The points with the midpoints to their k nearest neighbours added (their colours): a surface turned to face
    the camera spans more pixels than it was seen on, and would show holes between its points."""
    from scipy.spatial import cKDTree

    _, index = cKDTree(points).query(points, k=k + 1)
    mids = 0.5 * (points[:, None, :] + points[index[:, 1:]])
    return np.vstack([points, mids.reshape(-1, 3)]), np.vstack([colours, np.repeat(colours, k, axis=0)])


def _thin_axis(points: np.ndarray) -> np.ndarray | None:
    """The direction of an object's thinnest extent when it is flat (a plate), else None."""
    centred = points - points.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    return vt[2] if sv[2] < ON_EDGE_RATIO * sv[1] else None


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
