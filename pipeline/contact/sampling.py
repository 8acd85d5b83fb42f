"""Contact candidates on the object's point cloud (base frame, table top at z = 0).

Grasps: the fingers close along an axis y, the gripper approaches along z (straight down, leaning cfg.lean_deg about
y away from a tall neighbour, or from the side toward the object from the robot). The object's width between the
pads is measured on the cloud, and the antipodal quality is how well the surface normals at the two contact sides
line up with y. One camera sees only part of an object, so a side with no observed surface counts as half quality
instead of failing. Pads
closing at a slant on faces (a block's, a lying can's side) turn the object square to them as they squeeze, by
the slant (a lying can grasped 15 deg off square was set down 15 deg over its goal turn), so each grasp from
above is first turned about its approach axis square to the faces it closes on (_squared).
Pushes: closed fingers placed behind the object, opposite the direction it must move, tips first (see
push_candidates). Arc pushes on hinged
parts: hinge.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from pipeline.contact.tipping import flat_normal
from pipeline.contact.types import ContactConfig, ContactMode

PAD_HALF_WIDTH_M = 0.016  # half the finger pad's width (along the TCP x axis)
PAD_LENGTH_M = 0.06  # how far the pads reach from the TCP back toward the wrist
RAISED_M = 0.02  # scene points this high just below an object and around it are a raised support it stands on ...
SUPPORT_REACH_M = 0.04  # ... within this of its outline (the run's scene loses what lies within 1.5 cm of it) ...
SUPPORT_POINTS = 5  # ... when there are this many (the gate's cloud has a point per cm)
SUPPORT_CELL_M = 0.01  # the gate sees a support as points, in cells this large
TABLE_CLEAR_M = 0.002  # a push's padded fingertips (a side grasp's padded hand) this far above the table
SIDE_MIN_GRIP_M = 0.02  # a side grasp's pads (vertical, PAD_HALF_WIDTH_M about the TCP) hold this much of its height
FACES_MIN_CONCENTRATION = 0.65  # face_yaw: sides this concentrated on one direction (and those square to it) are flat
SQUARE_MIN_DEG = 1.0  # a grasp's closing axis this close to the faces' normals is square already
# a grasp from above pinching the object this many times wider than the narrowest pinch at the same spot closes
# across a flat part's slant (a plate standing in a rack cut at 60 deg): the part turns in the fingers or slips out
SLANT_RATIO = 2.0
# a part standing on a narrow edge (a plate in a rack: pinch width below THIN_RATIO of its height) leans a little
# between the capture and the grasp, or when a finger brushes it: its top sways up to SWAY_RAD times its height
THIN_RATIO = 0.2
SWAY_RAD = 0.1
STANDING_COS = 0.5  # a flat part whose faces' normal is this close to horizontal stands on its edge


@dataclass(frozen=True)
class Candidate:
    mode: ContactMode
    T_contact: np.ndarray
    object_width_m: float
    antipodal: float  # 0..1
    approach: float  # 1 straight down .. 0 horizontal
    centred: float  # 1 at the centroid .. 0 one object size away
    via: tuple[np.ndarray, ...] = ()  # TCP poses passed between contact and goal (an arc push)
    T_goal: np.ndarray | None = None  # None: T_contact carried by the object motion (rigid grasp or push)
    back_off: np.ndarray | None = None  # unit direction from contact to pre-contact (None: up the approach axis)
    sway_m: float = 0.0  # grasp: how far the pinched part may sway sideways (the fingers open that much wider)
    # grasp: the width the fingers close below, when narrower than object_width_m: what the seen points show
    # between the pads of a width measured on a completed surface (grasp_candidates' seen_points)
    grip_width_m: float | None = None


def frame(y: np.ndarray, z: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Right-handed TCP pose with closing axis y and approach axis z (y is made orthogonal to z)."""
    z = z / np.linalg.norm(z)
    y = y - (y @ z) * z
    y /= np.linalg.norm(y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    T[:3, 3] = origin
    return T


def estimate_normals(points: np.ndarray, radius_m: float, viewpoint: np.ndarray) -> np.ndarray:
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points.astype(np.float64)))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius_m, max_nn=30))
    pcd.orient_normals_towards_camera_location(viewpoint)
    return np.asarray(pcd.normals)


def _between_pads(points: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points in the frame of a gripper at T, and which of them lie between its pads."""
    local = (points - T[:3, 3]) @ T[:3, :3]
    return local, (np.abs(local[:, 0]) < PAD_HALF_WIDTH_M) & (local[:, 2] > -PAD_LENGTH_M) & (local[:, 2] < 0.003)


def _pinch(points: np.ndarray, normals: np.ndarray, T: np.ndarray) -> tuple[float, float, float] | None:
    """Width [m] of the object between the pads of a gripper at T, the antipodal quality, and the shift along
    the closing axis that centres the fingers on it; None if nothing lies between the pads."""
    local, slab = _between_pads(points, T)
    if slab.sum() < 5:
        return None
    y = local[slab, 1]
    lo, hi = y.min(), y.max()
    n_y = normals[slab] @ T[:3, 1]
    quality = []
    for side, sign in ((y < lo + 0.004, -1.0), (y > hi - 0.004, 1.0)):
        facing = sign * n_y[side]
        quality.append(float(np.clip(np.median(facing), 0, 1)) if facing.size >= 3 else 0.5)
    return float(hi - lo), float(np.mean(quality)), float(0.5 * (hi + lo))


def _squared(points: np.ndarray, normals: np.ndarray, T: np.ndarray) -> np.ndarray:
    """T turned about its approach axis so the closing axis lies along the normal of the faces between the pads:
    the weighted median direction, across the approach axis, of the contact sides' outward normals (the near
    side's reversed; a point facing up or down weighs little), each folded to within 45 deg of the closing axis (a
    face and those square to it are one choice: pads on a block's corner turn to the nearer pair of faces). T
    itself when it is square already or the pads close on no seen side."""
    local, slab = _between_pads(points, T)
    if slab.sum() < 5:
        return T
    y, n = local[slab, 1], normals[slab] @ T[:3, :3]  # normals in the TCP frame
    lo, hi = y.min(), y.max()
    facing = np.concatenate([-n[y < lo + 0.004], n[y > hi - 0.004]])[:, :2]  # across the approach axis
    weight = np.linalg.norm(facing, axis=1)
    if weight.sum() < 1e-9:
        return T
    angle = (np.arctan2(-facing[:, 0], facing[:, 1]) + np.pi / 4) % (np.pi / 2) - np.pi / 4  # from TCP y
    order = np.argsort(angle)
    cumulative = np.cumsum(weight[order])
    turn = float(angle[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])
    if abs(turn) < np.radians(SQUARE_MIN_DEG):
        return T
    c, s = np.cos(turn), np.sin(turn)
    out = T.copy()
    out[:3, :3] = T[:3, :3] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return out


def face_yaw(normals: np.ndarray) -> float | None:
    """The direction [rad, base frame] of the object's flat sides, up to quarter turns, or None when its sides are
    round or irregular: the mean of the outward normals' directions across the table, taken four times (a face and
    those square to it are one), each weighted by how far it lies across the table (a top weighs nothing). A block
    (two sides seen, edges blended) concentrates 0.7-0.9 of the weight on one direction, a lying can or bottle too
    (square to its axis), an upright can 0.1-0.5."""
    weight = np.linalg.norm(normals[:, :2], axis=1)
    if weight.sum() < 1e-9:
        return None
    mean = weight @ np.exp(4j * np.arctan2(normals[:, 1], normals[:, 0])) / weight.sum()
    return float(np.angle(mean)) / 4 if abs(mean) >= FACES_MIN_CONCENTRATION else None


def _square_to_faces(T: np.ndarray, faces_rad: float) -> np.ndarray:
    """T turned about its (vertical) approach axis so its closing axis lies along the nearest of the faces' normals:
    pads closed at a slant on a block's faces turn it square to them, by the slant."""
    closing = np.arctan2(T[1, 1], T[0, 1])
    turn = (faces_rad - closing + np.pi / 4) % (np.pi / 2) - np.pi / 4  # about the base's up axis
    out = T.copy()
    out[:3, :3] = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix() @ T[:3, :3]
    return out


def support_height(points: np.ndarray, scene: np.ndarray) -> float:
    """Height [m] of a raised support the object stands on (a stand's board), from the scene points seen just
    around and under its outline and just below its lowest point; 0 for the table (its points are not in the
    scene)."""
    if not len(scene):
        return 0.0
    bottom = float(np.percentile(points[:, 2], 2))
    low = scene[(scene[:, 2] > RAISED_M) & (scene[:, 2] < bottom + 0.005)]
    if len(low) < SUPPORT_POINTS:
        return 0.0
    near, _ = cKDTree(points[:, :2]).query(low[:, :2], distance_upper_bound=SUPPORT_REACH_M)
    under = low[np.isfinite(near)]
    return float(np.percentile(under[:, 2], 90)) if len(under) >= SUPPORT_POINTS else 0.0


def grasp_candidates(
    points: np.ndarray,
    normals: np.ndarray,
    cfg: ContactConfig,
    max_width_m: float,
    support_z: float = 0.0,
    seen_points: np.ndarray | None = None,
    gripper_tcp: np.ndarray | None = None,
) -> tuple[list[Candidate], dict[str, int]]:
    """support_z: the height of a raised support the object stands on (support_height), 0 on the table. gripper_tcp:
    the padded gripper's corners (TCP frame, open): a grasp from the side is made no lower than the hand, turned
    sideways, clears the table, and not at all when that leaves the pads too little of the object. seen_points:
    the points seen when `points` is a surface completed from them (a body of revolution): the fingers open and centre
    on the completed one, and close below the narrower width the seen points show between the pads (completed
    about an axis a few millimetres off, an upright bottle's shoulder read 8 mm wider than it is, and the fingers
    closed on it too lightly to hold it)."""
    rejected = {"too wide for the gripper": 0, "nothing between the fingers": 0, "across the object's slant": 0}
    rejected["too low to grasp from the side"] = 0
    centroid = points.mean(axis=0)
    size = float(np.linalg.norm(np.percentile(points, 95, axis=0) - np.percentile(points, 5, axis=0)))
    top = float(np.percentile(points[:, 2], 98))
    down = np.array([0.0, 0.0, -1.0])
    poses, spots = [], []  # spots: which top-grasp origin a pose is at (None from the side)
    # from above: closing axis swept in the horizontal plane, centred on the top surface (which one view sees
    # whole, unlike the sides) and, for elongated objects, also along the long axis
    upper = points[points[:, 2] > top - 0.01]
    centre_xy = upper[:, :2].mean(axis=0) if len(upper) >= 10 else centroid[:2]
    xy = points[:, :2] - centre_xy
    axes = np.linalg.svd(xy - xy.mean(axis=0), full_matrices=False)[2]
    spread = np.percentile(np.abs(xy @ axes.T), 90, axis=0)
    offsets = (0.0, -0.5 * spread[0], 0.5 * spread[0]) if spread[0] > 1.6 * spread[1] else (0.0,)
    # the object's own height, and the fingers' clearance, from what it stands on: the table, or a raised support
    # (support_z: a stand, seen as points in cells of up to SUPPORT_CELL_M by the gate)
    floor = cfg.min_tcp_height_m + (support_z + SUPPORT_CELL_M if support_z > 0.0 else 0.0)
    height = max(top - min(cfg.grasp_depth_m, 0.75 * (top - support_z)), floor)
    # a flat part standing on its edge (a plate leaning in a rack) is pinched square to its faces, the approach down
    # its own plane (straight down, a leaning plate lies across the pads and turns or slips out as they close)
    normal = flat_normal(points)
    standing = normal is not None and abs(normal[2]) < STANDING_COS
    for spot, offset in enumerate(offsets):
        origin = np.array([*(centre_xy + offset * axes[0]), height])
        if standing:
            poses.append(frame(normal, down - (down @ normal) * normal, origin))
            spots.append(spot)
            continue
        for yaw in np.radians(np.arange(0.0, 180.0, cfg.yaw_step_deg)):
            poses.append(frame(np.array([np.cos(yaw), np.sin(yaw), 0.0]), down, origin))
            spots.append(spot)
    # from the side: horizontal approach from the robot's side, closing axis horizontal
    toward = np.array([centroid[0], centroid[1], 0.0])
    toward /= max(np.linalg.norm(toward), 1e-9)
    for angle in np.radians(cfg.side_approach_deg):
        c, s = np.cos(angle), np.sin(angle)
        z = np.array([c * toward[0] - s * toward[1], s * toward[0] + c * toward[1], 0.0])
        T = frame(np.cross([0.0, 0.0, 1.0], z), z, np.zeros(3))
        clear = 0.0 if gripper_tcp is None else -float(np.min((gripper_tcp @ T[:3, :3].T)[:, 2])) + TABLE_CLEAR_M
        side_height = max(0.5 * (top + support_z), floor, clear)
        held = min(top, side_height + PAD_HALF_WIDTH_M) - max(support_z, side_height - PAD_HALF_WIDTH_M)
        if held < SIDE_MIN_GRIP_M:  # raised till the sideways hand clears the table, the pads pass over a low object
            rejected["too low to grasp from the side"] += 1
            continue
        T[:3, 3] = [centre_xy[0], centre_xy[1], side_height]
        poses.append(T)
        spots.append(None)
    # from above: squared to the flat sides (found on the whole object: the pads' own few points, at a slant, end on
    # a block's corners and blend both faces), else to the sides between the pads
    faces = face_yaw(normals)
    square = (lambda T: _square_to_faces(T, faces)) if faces is not None else (lambda T: _squared(points, normals, T))
    poses = [square(T) if T[2, 2] < -0.99 else T for T in poses]
    leaning = [
        (lean, spot)
        for T, spot in zip(poses, spots, strict=True)
        if spot is not None
        for lean in _leaning(T, gripper_tcp, cfg.lean_deg)
    ]
    poses, spots = poses + [T for T, _ in leaning], spots + [spot for _, spot in leaning]
    kept, seen = [], set()
    for T, spot in zip(poses, spots, strict=True):
        closing = np.degrees(np.arctan2(T[1, 1], T[0, 1])) % 180.0  # squared sweeps meet: one grasp each
        key = (*np.round(T[:3, 3], 4), round(closing) % 180, *np.round(T[:3, 2], 2))
        if key not in seen:
            seen.add(key)
            kept.append((T, spot))
    pinches = [_pinch(points, normals, T) for T, _ in kept]
    narrowest: dict[int, float] = {}
    for (_, spot), pinch in zip(kept, pinches, strict=True):
        if spot is not None and pinch is not None:
            narrowest[spot] = min(narrowest.get(spot, np.inf), pinch[0])
    out = []
    for (T, spot), pinch in zip(kept, pinches, strict=True):
        if pinch is None:
            rejected["nothing between the fingers"] += 1
            continue
        width, antipodal, shift = pinch
        if spot is not None and width > SLANT_RATIO * max(narrowest[spot], 0.01):
            rejected["across the object's slant"] += 1
            continue
        T = T.copy()
        T[:3, 3] += shift * T[:3, 1]
        if width + 2 * cfg.min_finger_clearance_m > max_width_m:
            rejected["too wide for the gripper"] += 1
            continue
        approach = float(np.clip(T[:3, 2] @ down, 0.0, 1.0))
        centred = float(np.clip(1.0 - 2 * np.linalg.norm(T[:2, 3] - centre_xy) / max(size, 1e-6), 0.0, 1.0))
        tall = top - support_z
        sway = SWAY_RAD * tall if spot is not None and width < THIN_RATIO * tall else 0.0
        grip = None
        if seen_points is not None:
            local, slab = _between_pads(seen_points, T)
            grip = float(np.ptp(local[slab, 1])) if slab.sum() >= 5 and np.ptp(local[slab, 1]) < width else None
        out.append(Candidate("grasp", T, width, antipodal, approach, centred, sway_m=sway, grip_width_m=grip))
    return out, rejected


def _leaning(T: np.ndarray, gripper_tcp: np.ndarray | None, lean_deg: float) -> list[np.ndarray]:
    """T turned lean_deg each way about its closing axis through the TCP, each raised as far as its lowest gripper
    corner (gripper_tcp, TCP frame) went below the straight grasp's."""
    out = []
    if lean_deg <= 0.0:
        return out
    for sign in (-1.0, 1.0):
        lean = T.copy()
        lean[:3, :3] = Rotation.from_rotvec(sign * np.radians(lean_deg) * T[:3, 1]).as_matrix() @ T[:3, :3]
        if gripper_tcp is not None:
            lean[2, 3] += max(0.0, float(np.min(gripper_tcp @ T[2, :3])) - float(np.min(gripper_tcp @ lean[2, :3])))
        out.append(lean)
    return out


def push_candidates(
    points: np.ndarray,
    shift: np.ndarray,
    cfg: ContactConfig,
    gripper_tcp: np.ndarray,
    fingers_tcp: np.ndarray,
) -> list[Candidate]:
    """Closed fingers behind the object (opposite the horizontal shift), pushing it by the shift.

    The fingers lead with their tips, the hand tilted cfg.push_tilt_deg back from the push: only the tips touch,
    as low as the padded gripper clears the table (gripper_tcp: its corners, TCP frame), so the push acts below
    the object's centre of mass and a tall or narrow object slides instead of tipping over; upright fingers
    pressing with their whole length (the object's lower third and up) are the fallback. Each comes with the
    broad side of the closed fingers to the object and turned a quarter turn (another wrist; the half turn is the
    planner's twin). The push ends where the fingers' front (fingers_tcp: unpadded finger corners) has travelled
    the shift beyond the gap it started from, so the object moves by the shift, not by the shift less the gap.
    `antipodal` ranks them here (tips first before upright, broad side before quarter-turned), `approach` is 1.
    """
    d = np.array([shift[0], shift[1], 0.0])
    distance = float(np.linalg.norm(d))
    if distance < 1e-6:
        return []
    d /= distance
    up = np.array([0.0, 0.0, 1.0])
    side = np.cross(up, d)
    along, across = points @ d, points @ side
    back_along = float(np.percentile(along, 2))  # where the fingers first touch
    middle = 0.5 * float(np.percentile(across, 2) + np.percentile(across, 98))  # the line through the object's width
    back_xy = back_along * d[:2] + middle * side[:2]
    centroid = points.mean(axis=0)
    top = float(np.percentile(points[:, 2], 98))
    out = []
    kinds = ((1.0, cfg.push_tilt_deg, False), (0.8, cfg.push_tilt_deg, True), (0.5, 0.0, False), (0.4, 0.0, True))
    for preference, tilt_deg, quarter in kinds:
        tilt = np.radians(tilt_deg)
        z = np.cos(tilt) * -up + np.sin(tilt) * d  # tips toward the object, the hand behind and above
        y = d if quarter else side
        T = frame(y, z, np.zeros(3))
        front = float(np.max(fingers_tcp @ T[:3, :3].T @ d))  # how far the fingers reach ahead of the TCP
        if tilt_deg > 0:  # as low as the padded gripper clears the table
            height = max(cfg.min_tcp_height_m, -float(np.min(gripper_tcp @ T[:3, :3].T[:, 2])) + TABLE_CLEAR_M)
        else:
            height = max(0.35 * top, cfg.min_tcp_height_m)
        xy = back_xy - (cfg.push_standoff_m + front) * d[:2]
        T[:3, 3] = [xy[0], xy[1], height]
        gap = back_along - (T[:3, 3] @ d + front)  # between the fingers' front and the object's back
        T_goal = T.copy()
        T_goal[:3, 3] += (distance + gap) * d
        lateral = np.linalg.norm((T[:2, 3] - centroid[:2]) - ((T[:2, 3] - centroid[:2]) @ d[:2]) * d[:2])
        centred = float(np.clip(1 - lateral / 0.05, 0, 1))
        out.append(Candidate("push", T, 0.0, preference, 1.0, centred, T_goal=T_goal))
    return out
