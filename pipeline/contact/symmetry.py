"""The axis a body of revolution turns about, from the part of its surface one camera sees (base frame).

A bottle, can or ball looks the same after any turn about its own axis, so the grounded motion's turn about that
axis is not seen in the images: it is whatever the registration settled on, and a grasp carried by it may end in
a wrist pose the arm cannot take while the same object goal, turned about its axis, is easy. The axis is found
among the cloud's principal directions as the one whose slices across it are circles about one common line. A
body whose slices have one radius all along its middle (a can, not a bottle with its neck) also looks the same
turned end for end.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from safety.geometry import turn_about

SLICE_M = 0.005  # slice thickness along the candidate axis
TOLERANCE_REL = 0.02  # median distance off the fitted surface / object size (bottles ~0.005, boxes >= 0.027)
MIN_POINTS = 50
ENDS_ALIKE_REL = 0.1  # slices' radii within this share of their median all along: the ends look alike (a can) ...
END_MARGIN_REL = 0.1  # ... over the middle of the seen length (an end's cap, a disc of smaller radii, left out) ...
MIN_SLICE_POINTS = 5  # ... in slices of at least this many points
RIM_PERCENTILE = 95  # of a slice's distances from the axis: its rim, not a stray
BALL_SPAN = 0.4  # a ball's radius is at most this share of what its seen points span (their extents' norm)


@dataclass(frozen=True)
class RevolutionAxis:
    point: np.ndarray  # a point on the axis (base frame), at the cloud's middle along it
    direction: np.ndarray  # unit vector along the axis
    radius_m: float  # median distance of the points from the axis
    residual_rel: float  # median distance off the fitted surface / object size
    ends_alike: bool = False  # one radius all along (a can, not a bottle): turned end for end it looks the same

    def turn(self, angle_rad: float) -> np.ndarray:
        """4x4 rigid turn by angle_rad about this axis (base frame)."""
        return turn_about(self.point, self.direction, angle_rad)

    def completed(self, points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The seen surface (points and outward normals, base frame) and the same turned half a turn about the
        axis: the side one camera does not see (a lying bottle's side away from the camera, below its top), where
        a finger closes too."""
        T = self.turn(np.pi)
        points, normals = np.asarray(points, dtype=np.float64), np.asarray(normals, dtype=np.float64)
        return (
            np.vstack([points, points @ T[:3, :3].T + T[:3, 3]]),
            np.vstack([normals, normals @ T[:3, :3].T]),
        )


def ball_centre(points: np.ndarray) -> np.ndarray | None:
    """The centre of the ball the points (N, 3) lie on, or None when they lie on no sphere no larger than they
    span (no turn of a ball shows, so only where its centre goes matters)."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(P) < MIN_POINTS:
        return None
    centre = np.linalg.lstsq(np.column_stack([2 * P, np.ones(len(P))]), (P**2).sum(axis=1), rcond=None)[0][:3]
    radius = np.linalg.norm(P - centre, axis=1)
    off = float(np.median(np.abs(radius - np.median(radius))))
    size = float(np.linalg.norm(np.ptp(P, axis=0)))
    # a flat part lies nearly on a sphere too, a large one: a ball's seen side (a cap of 60 deg half-angle or more)
    # spans 2.5 radii or more
    return centre if off <= TOLERANCE_REL * size and float(np.median(radius)) <= BALL_SPAN * size else None


def completed_points(points: np.ndarray) -> np.ndarray:
    """The seen points (N, 3) with the side the camera does not see, where the object's shape tells it: a ball's
    points mirrored through its centre, a body of revolution's turned half a turn about its axis; anything else
    as seen. A push starts behind the object and through its middle: on a can's seen half, its back (away from
    the camera) falls short by the eroded rim and its middle lies toward the camera by about half a radius."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    centre = ball_centre(P)
    if centre is not None:
        return np.vstack([P, 2.0 * centre - P])
    body = revolution_axis(P)
    return P if body is None else body.completed(P, np.zeros_like(P))[0]


def turn_deg(T_a: np.ndarray, T_b: np.ndarray) -> float:
    """The angle [deg] of the rotation between two motions (4x4): how far a plan's turns from the grounded one."""
    cos = (np.trace(T_a[:3, :3] @ T_b[:3, :3].T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def _fit(points: np.ndarray, axis: np.ndarray, size: float) -> RevolutionAxis:
    """Circles about one line along `axis`, one radius per slice: x^2 + y^2 = 2 x0 x + 2 y0 y + c_slice."""
    e1, e2 = basis_across(axis)
    s = points @ axis
    uv = np.column_stack([points @ e1, points @ e2])
    labels, slice_of = np.unique(np.floor((s - s.min()) / SLICE_M).astype(int), return_inverse=True)
    # each slice's c taken out by centring on the slice's means: the same (x0, y0) as solving for every c too, without
    # a dense column per slice (a least-squares problem of N x (2 + slices) took 60 ms on a few thousand points)
    count = np.bincount(slice_of)
    A, b = 2 * uv, (uv**2).sum(axis=1)
    A = A - np.column_stack([np.bincount(slice_of, A[:, k]) / count for k in range(2)])[slice_of]
    b = b - (np.bincount(slice_of, b) / count)[slice_of]
    u0, v0 = np.linalg.lstsq(A, b, rcond=None)[0]
    radius = np.hypot(uv[:, 0] - u0, uv[:, 1] - v0)
    per_slice = np.array([np.median(radius[slice_of == k]) for k in range(len(labels))])
    residual = float(np.median(np.abs(radius - per_slice[slice_of]))) / size
    point = u0 * e1 + v0 * e2 + float(np.median(s)) * axis
    return RevolutionAxis(point, axis, float(np.median(radius)), residual)


def basis_across(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(e1, e2): unit vectors across the unit `axis`, with (e1, e2, axis) right-handed; set by the axis alone, so
    angles measured about one axis in two views compare."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def _middle_slices(points: np.ndarray, axis: np.ndarray) -> list[np.ndarray]:
    """The points of each SLICE_M slice across `axis` over the middle of the seen length (END_MARGIN_REL of it
    left out at each end, where a cap's disc lies), each of at least MIN_SLICE_POINTS."""
    s = points @ axis
    margin = END_MARGIN_REL * (s.max() - s.min())
    keep = (s >= s.min() + margin) & (s <= s.max() - margin)
    index = np.floor((s - s.min()) / SLICE_M).astype(int)
    slices = [points[keep & (index == k)] for k in np.unique(index[keep])]
    return [p for p in slices if len(p) >= MIN_SLICE_POINTS]


def _refined(points: np.ndarray, axis: RevolutionAxis) -> RevolutionAxis:
    """The axis refined through the centres of circles fitted to each slice across it (twice), the radius the
    points' median distance from it; the axis as it is when fewer than 3 slices hold enough points. The principal
    direction of a short, wide can's seen half is off by up to 10 deg, tilted out of the table's plane: turned
    about it, a can stood up leans, and its taper reads as a neck."""
    direction, point = axis.direction, axis.point
    for _ in range(2):
        e1, e2 = basis_across(direction)
        centres = []
        for p in _middle_slices(points, direction):
            uv = np.column_stack([p @ e1, p @ e2])
            A = np.column_stack([2 * uv, np.ones(len(p))])
            u0, v0, _ = np.linalg.lstsq(A, (uv**2).sum(axis=1), rcond=None)[0]
            centres.append(u0 * e1 + v0 * e2 + float(np.mean(p @ direction)) * direction)
        if len(centres) < 3:
            return axis
        C = np.array(centres)
        point = C.mean(axis=0)
        refined = np.linalg.svd(C - point, full_matrices=False)[2][0]
        direction = refined if refined @ direction > 0 else -refined
    off = points - point
    radius = float(np.median(np.linalg.norm(off - np.outer(off @ direction, direction), axis=1)))
    return replace(axis, point=point, direction=direction, radius_m=radius)


def slice_radii(
    points: np.ndarray, point: np.ndarray, direction: np.ndarray, percentile: float = 50.0
) -> tuple[np.ndarray, np.ndarray]:
    """(position along the axis through `point` along unit `direction`, radius: the `percentile` of the points'
    distances from the axis, their median by default) of each SLICE_M slice across it over the whole seen length,
    each of at least MIN_SLICE_POINTS points."""
    off = points - point
    along = off @ direction
    radius = np.linalg.norm(off - np.outer(along, direction), axis=1)
    index = np.floor((along - along.min()) / SLICE_M).astype(int)
    kept = [k for k in np.unique(index) if (index == k).sum() >= MIN_SLICE_POINTS]
    return (
        np.array([float(np.mean(along[index == k])) for k in kept]),
        np.array([float(np.percentile(radius[index == k], percentile)) for k in kept]),
    )


def revolved(points: np.ndarray, point: np.ndarray, direction: np.ndarray, azimuths: int = 24) -> np.ndarray:
    """(N, 3) points on the whole of a body of revolution seen from one side: each slice of its seen `points` along
    the axis through `point` along unit `direction` (slice_radii) spun all the way round at the slice's radius, its
    RIM_PERCENTILE (a rim, not a stray)."""
    heights, radii = slice_radii(points, point, direction, RIM_PERCENTILE)
    e1, e2 = basis_across(direction)
    azimuth = np.linspace(0.0, 2.0 * np.pi, azimuths, endpoint=False)
    ring = np.outer(np.cos(azimuth), e1) + np.outer(np.sin(azimuth), e2)
    return (point + heights[:, None, None] * direction + radii[:, None, None] * ring).reshape(-1, 3)


def ends_alike(points: np.ndarray, point: np.ndarray, direction: np.ndarray) -> bool:
    """Whether the body has one radius all along the middle of its seen length (within ENDS_ALIKE_REL of the
    median) about the axis through `point` along `direction` (unit): no neck, no shoulder, nothing to tell one end
    from the other."""
    radii = []
    for p in _middle_slices(points, direction):
        off = p - point
        radii.append(float(np.median(np.linalg.norm(off - np.outer(off @ direction, direction), axis=1))))
    if len(radii) < 3:
        return False
    typical = float(np.median(radii))
    return bool(np.max(np.abs(np.array(radii) - typical)) <= ENDS_ALIKE_REL * typical)


def revolution_axis(points: np.ndarray) -> RevolutionAxis | None:
    """The axis of the body of revolution the points (N, 3) lie on, or None when they lie on none."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(P) < MIN_POINTS:
        return None
    size = float(np.linalg.norm(np.ptp(P, axis=0)))
    if size <= 0.0:
        return None
    directions = np.linalg.svd(P - P.mean(axis=0), full_matrices=False)[2]
    best = min((_fit(P, d, size) for d in directions), key=lambda f: f.residual_rel)
    if best.residual_rel > TOLERANCE_REL:
        return None
    refined = _refined(P, best)
    return replace(refined, ends_alike=ends_alike(P, refined.point, refined.direction))
