"""A hand tool lying on the table, from its seen points: which end works (a brush's head) and which is held.

A brush, a scraper or a squeegee is long and flat: a working end wider than the handle that reaches back from it.
Along the tool's long axis (the principal axis of its points on the table) the width profile says which end is
which: the wider end is the head, the narrow rest the handle. The head's front edge (its far side from the
handle) is what pushes, its width how wide a lane one stroke clears.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from safety.geometry import Primitive

BIN_M = 0.01  # width profile step along the tool's axis
HEAD_FRACTION = 0.6  # a slice at least this share of the widest is part of the head
MIN_HEAD_RATIO = 1.6  # the head must be this much wider than the handle to tell the ends apart
MIN_POINTS = 50
BOX_MARGIN_M = 0.003  # the held tool's box beyond its seen extent (its edges' depth is noisy)


class ToolError(ValueError):
    """The points do not show a tool with a working end and a handle; the message says what was seen."""


@dataclass(frozen=True)
class ToolShape:
    """A tool at rest, base frame (table top at z = 0)."""

    points: np.ndarray  # every seen point of the tool
    head: np.ndarray  # the working end's points
    handle: np.ndarray  # the handle's points
    axis: np.ndarray  # (3,) horizontal unit vector from the handle towards the head
    front: np.ndarray  # (3,) middle of the head's front edge, on the table
    head_width_m: float  # across the axis
    head_depth_m: float  # along it
    handle_width_m: float


def tool_shape(points: np.ndarray) -> ToolShape:
    """The tool's working end and handle from its points (N, 3), base frame; ToolError when they cannot be told."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) < MIN_POINTS:
        raise ToolError(f"the tool shows {len(pts)} points with depth (need {MIN_POINTS})")
    xy = pts[:, :2] - pts[:, :2].mean(axis=0)
    axis2 = np.linalg.svd(xy, full_matrices=False)[2][0]
    s, w = xy @ axis2, xy @ np.array([-axis2[1], axis2[0]])
    edges = np.arange(np.percentile(s, 1), np.percentile(s, 99) + BIN_M, BIN_M)
    index = np.clip(np.digitize(s, edges) - 1, 0, len(edges) - 1)
    width = np.array(
        [np.ptp(np.percentile(w[index == k], [3, 97])) if (index == k).sum() >= 5 else 0.0 for k in range(len(edges))]
    )
    ends = max(1, len(edges) // 4)
    if width[-ends:].mean() < width[:ends].mean():  # the head is the wider end: make +s point to it
        axis2, s, w = -axis2, -s, -w
        width, index = width[::-1], len(edges) - 1 - index
    widest = float(width.max())
    head_bins = np.flatnonzero(width >= HEAD_FRACTION * widest)
    first = int(head_bins.min())
    head = index >= first
    handle = index < first - 1
    handle_width = float(np.median(width[: max(first - 1, 1)])) if handle.any() else 0.0
    if handle.sum() < 10 or widest < MIN_HEAD_RATIO * max(handle_width, 1e-3):
        raise ToolError(
            f"no working end wider than a handle: widest {widest * 1000:.0f} mm, handle {handle_width * 1000:.0f} mm "
            f"across ({handle.sum()} handle points)"
        )
    axis = np.array([axis2[0], axis2[1], 0.0])
    across = np.array([-axis2[1], axis2[0], 0.0])
    centre = np.array([*pts[:, :2].mean(axis=0), 0.0])
    hs, hw = s[head], w[head]
    front = centre + float(np.percentile(hs, 99)) * axis + 0.5 * float(np.sum(np.percentile(hw, [2, 98]))) * across
    front[2] = 0.0
    return ToolShape(
        points=pts,
        head=pts[head],
        handle=pts[handle],
        axis=axis,
        front=front,
        head_width_m=float(np.ptp(np.percentile(hw, [2, 98]))),
        head_depth_m=float(np.ptp(np.percentile(hs, [1, 99]))),
        handle_width_m=handle_width,
    )


def tool_box(shape: ToolShape, T_base_tcp: np.ndarray, *, tcp_link: str, name: str) -> Primitive:
    """The tool as the gate sees it once grasped at T_base_tcp: the box of its points in its own frame (along its
    axis, across it, up), from the table it lies on to its top, in the TCP frame. A box along the TCP's axes would
    be much larger for a tool grasped at a slant. Seen from above, a flat tool shows its whole outline; its
    underside is the table it lies on."""
    x = shape.axis
    y = np.cross([0.0, 0.0, 1.0], x)
    R = np.column_stack([x, y, [0.0, 0.0, 1.0]])
    local = shape.points @ R
    lo, hi = np.percentile(local, [0.5, 99.5], axis=0)  # a few stray edge points are not the tool
    lo = np.array([lo[0] - BOX_MARGIN_M, lo[1] - BOX_MARGIN_M, 0.0])  # it lay on the table
    hi = hi + BOX_MARGIN_M
    T_base_box = np.eye(4)
    T_base_box[:3, :3] = R
    T_base_box[:3, 3] = R @ (0.5 * (lo + hi))
    return Primitive(f"held:{name}", tcp_link, "box", tuple(hi - lo), np.linalg.inv(T_base_tcp) @ T_base_box)
