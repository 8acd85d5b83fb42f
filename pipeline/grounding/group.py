"""Grounding a group of like parts (the screws of a sweep): the motion of the parts' centroid.

Why the centroid and not one motion per part: a sweep does not keep the parts' arrangement (they roll, bunch up
and pile in the dustpan), like parts cannot be told apart between the two images, and a generated goal image draws
them where it likes. What the contact needs is where the group is and where it must go; what verification needs
is how many parts ended inside the container (pipeline.grounding.group_count). So the group's motion is a
translation: the centroid of its parts' points in the goal view (the goal depth aligned on the background like a
single object's) less their centroid in the initial view; R is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from drivers.types import CameraIntrinsics
from pipeline.grounding.prepare import align_goal_depth, object_size, refuse
from pipeline.grounding.types import GroundingConfig, GroundingInput, ObjectMotion
from safety.geometry import transform_points

MIN_GROUP_POINTS = 20  # points with depth a group needs in each view
CONTAINER_ABOVE_M = 0.02  # a part counts as in a container up to this far above the container's top
MIN_HEIGHT_M = 0.002  # a seen point's height above the table counts at least this (depth noise at the table)
FLOOR_BAND_M = 0.006  # a container's points this close above its lowest are its floor ...
FLOOR_DENSE_M, FLOOR_NEIGHBOURS = 0.01, 20  # ... where they are dense (within 1 cm, a 1 m view has ~40 of them)
WALL_ABOVE_M = 0.01  # container points this high above its floor are its walls
WALLED_MARGIN_M = 0.012  # a part's centre at least this far inside a wall's outer face (past a wall's top) ...
OPEN_MARGIN_M = 0.02  # ... and this far along an open edge (a dustpan's lip): a part half over it is not in
WALL_TOP_BAND_M = 0.005  # a container's points this close below its highest are its walls' tops
ON_WALL_NEAR_M, ON_WALL_ABOVE_M = 0.006, 0.003  # a part's point this near a wall's top and this far above it rests
# on the wall (a part on the floor against a wall reaches no higher than the wall's top that close to it)


def _edge_margins(floor: ConvexHull, walls_xy: np.ndarray) -> np.ndarray:
    """Per edge of the floor's outline, how far inside it a part's centre must be: a little along a wall (the
    wall keeps parts in), more along an open edge (a part there may hang over it)."""
    margins = np.full(len(floor.equations), OPEN_MARGIN_M)
    for k, (simplex, eq) in enumerate(zip(floor.simplices, floor.equations, strict=True)):
        a, b = floor.points[simplex]
        along = (walls_xy - a) @ (b - a) / max(float(np.dot(b - a, b - a)), 1e-12)
        out = walls_xy @ eq[:2] + eq[2]  # > 0: outside this edge
        if np.sum((along > 0.1) & (along < 0.9) & (out > -0.01) & (out < 0.02)) >= 5:
            margins[k] = WALLED_MARGIN_M
    return margins


def ground_group(
    inp: GroundingInput, config: GroundingConfig | None = None, T_base_camera: np.ndarray | None = None
) -> ObjectMotion:
    """The group's centroid motion (x_goal = x_init + t, camera frame) or a refusal with its reason."""
    cfg = config or GroundingConfig()
    K = inp.intrinsics
    aligned = align_goal_depth(inp, cfg, T_base_camera, "group: ")
    if isinstance(aligned, ObjectMotion):
        return aligned
    depth0, depth1, align = aligned
    common = {"depth_residual_m": align.residual_m, "T_base_camera": T_base_camera}
    valid0, valid1 = inp.mask0 & np.isfinite(depth0), inp.mask1 & np.isfinite(depth1)
    if valid0.sum() < MIN_GROUP_POINTS or valid1.sum() < MIN_GROUP_POINTS:
        return refuse(
            f"group: too few points with depth: {valid0.sum()} initial, {valid1.sum()} goal (need {MIN_GROUP_POINTS})",
            **common,
        )
    p0 = K.unproject_depth_image(depth0)[valid0]
    p1 = K.unproject_depth_image(depth1)[valid1]
    t = p1.mean(axis=0) - p0.mean(axis=0)
    return ObjectMotion(
        ok=True,
        reason=f"group: its parts' centroid moves {np.linalg.norm(t) * 1000:.0f} mm",
        t=t,
        inliers=int(valid1.sum()),
        confidence=float(np.exp(-align.residual_m / cfg.max_depth_residual_m)),
        object_size_m=object_size(p0),
        details={"group": True, "points_initial": int(valid0.sum()), "points_goal": int(valid1.sum())},
        **common,
    )


@dataclass(frozen=True)
class GroupCount:
    """How many of a group's parts lie inside a container after a sweep, by the camera alone.

    Touching parts are one region, in either capture, so a region counts as its bulk (seen metric area times height
    above the table, _bulk) over one part's, at least one; one part's is the median of the initial regions' (most
    parts lie apart before a sweep)."""

    total: int  # parts in the initial image
    inside: int  # estimated parts inside the container's outline
    outside: int  # estimated parts elsewhere
    regions: tuple[tuple[float, float, int, bool], ...]  # per region: base x, y, parts, inside

    @property
    def fraction(self) -> float:
        return self.inside / max(self.total, 1)


def _bulk(
    mask: np.ndarray, depth: np.ndarray, K: CameraIntrinsics, T_base_camera: np.ndarray, base_z: float = 0.0
) -> float:
    """How much of the parts a region holds, up to a constant: its seen surface's metric area (pixels times depth
    squared) times its height above what it rests on (base_z: the table's 0, a wall's top). A pile shows only its
    top layer: its area alone counts it low, its height makes up for the layers under it."""
    valid = mask & np.isfinite(depth)
    if not valid.any():
        return 0.0
    z = depth[valid]
    height = transform_points(T_base_camera, K.unproject_depth_image(depth)[valid])[:, 2] - base_z
    return float(np.sum(z**2 * np.clip(height, MIN_HEIGHT_M, None)))


def _on_walls(
    mask: np.ndarray, depth: np.ndarray, K: CameraIntrinsics, T_base_camera: np.ndarray, tops: cKDTree, top_z: float
) -> np.ndarray:
    """The region's pixels resting on a wall of the container: above the walls' top, over it (tops: the walls'
    top points, base x, y). Such a part is not in the container, whatever the region it touches."""
    valid = mask & np.isfinite(depth)
    p = transform_points(T_base_camera, K.unproject_depth_image(depth)[valid])
    near = tops.query(p[:, :2], distance_upper_bound=ON_WALL_NEAR_M)[0] < np.inf
    out = np.zeros_like(mask)
    out[valid] = near & (p[:, 2] > top_z + ON_WALL_ABOVE_M)
    return out


def count_in_container(
    *,
    depth0: np.ndarray,
    K0: CameraIntrinsics,
    T_base_camera0: np.ndarray,
    group0: np.ndarray,
    container0: np.ndarray,
    depth1: np.ndarray,
    K1: CameraIntrinsics,
    T_base_camera1: np.ndarray,
    parts1: list[np.ndarray],
) -> GroupCount:
    """The parts seen after (parts1: one mask per region) counted inside the container: each region whose centroid
    lies within the container's outline as first seen (its dense floor points and its walls, base frame) and past
    its walls' tops; a part resting on a wall's top is not in it, even touching parts inside (its pixels over the
    wall above its top are a region of their own, outside); group0: the initial group's union mask."""
    n, labels = cv2.connectedComponents(group0.astype(np.uint8), connectivity=8)
    areas = np.array([_bulk(labels == k, depth0, K0, T_base_camera0) for k in range(1, n)])
    areas = areas[areas > 0]
    if not len(areas):
        raise ValueError("count_in_container: the initial group shows no part with depth")
    unit = float(np.median(areas))
    group_size = int(sum(max(1, round(a / unit)) for a in areas))
    pts = transform_points(T_base_camera0, K0.unproject_depth_image(depth0)[container0 & np.isfinite(depth0)])
    if len(pts) < 20:
        raise ValueError(f"count_in_container: the container shows {len(pts)} points with depth")
    low = pts[pts[:, 2] < np.percentile(pts[:, 2], 3) + FLOOR_BAND_M, :2]  # its floor (and lip): inside its walls
    neighbours = cKDTree(low).query_ball_point(low, FLOOR_DENSE_M, return_length=True)
    low = low[neighbours >= FLOOR_NEIGHBOURS]  # not a rim of mixed pixels at the mask's edge (the table's)
    if len(low) < 20:
        raise ValueError("count_in_container: the container shows no floor")
    wall_points = pts[pts[:, 2] > np.percentile(pts[:, 2], 3) + WALL_ABOVE_M]
    walls = wall_points[:, :2]
    floor = ConvexHull(np.vstack([low, walls]))  # to the walls' outer faces: a wall hides the floor behind it
    margins = _edge_margins(floor, walls)
    wall_top = float(np.percentile(pts[:, 2], 98))
    top = wall_top + CONTAINER_ABOVE_M
    tops = cKDTree(walls[wall_points[:, 2] > wall_top - WALL_TOP_BAND_M])
    regions = []
    for region in parts1:
        on_wall = _on_walls(region, depth1, K1, T_base_camera1, tops, wall_top) if len(tops.data) else None
        # (pixels, the height they rest on, in or not (None: by where they are), the fewest parts they count)
        pieces = [(region, 0.0, None, 1)]
        if on_wall is not None and round(_bulk(on_wall, depth1, K1, T_base_camera1, wall_top) / unit) >= 1:
            pieces = [(on_wall, wall_top, False, 1), (region & ~on_wall, 0.0, None, 0)]  # the rest: its own bulk
        for mask, base_z, verdict, fewest in pieces:
            valid = mask & np.isfinite(depth1)
            parts = max(fewest, round(_bulk(mask, depth1, K1, T_base_camera1, base_z) / unit))
            if not valid.any() or parts == 0:
                continue
            p = transform_points(T_base_camera1, K1.unproject_depth_image(depth1)[valid]).mean(axis=0)
            over_floor = np.all(floor.equations[:, :2] @ p[:2] + floor.equations[:, 2] <= -margins)
            inside = bool(over_floor and p[2] < top) if verdict is None else verdict
            regions.append((float(p[0]), float(p[1]), int(parts), inside))
    outside = sum(r[2] for r in regions if not r[3])
    # an area is a loose count (a part lying askew shows more of itself): the parts seen elsewhere bound it
    inside = max(0, min(group_size - outside, sum(r[2] for r in regions if r[3])))
    return GroupCount(group_size, inside, outside, tuple(regions))
