"""Initial/goal pairs with a known object motion, rendered by this package's own ray caster with domain
randomisation (camera, table, lighting, objects, textures, motions, and every corruption in corrupt.py).

Pair i of seed s is drawn from its own generator (seed, i), so sets are reproducible and a seed used for tuning
never overlaps one used for the reported figures. Motion kinds: `slide` (5-40 cm in any direction, any yaw),
`turn` (in place: under 1.5 cm, 20-180 deg about the vertical), `tip` (tilted 20-90 deg about a horizontal axis,
half of them exactly 90, any yaw, shifted up to 40 cm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from bench.pairgen.corrupt import (
    CORRUPTIONS,
    editor_drift,
    monocular_depth,
    segmenter_mask,
    sensor_depth,
    sensor_image,
)
from bench.pairgen.materials import Material, partially_retextured, random_material, table_material
from bench.pairgen.render import Light, Placed, render, silhouette, visible
from bench.pairgen.shapes import CUBE_ROTATIONS, KINDS, Shape, make_shape
from drivers.types import CameraIntrinsics

MOTION_KINDS = ("slide", "turn", "tip")
TARGET_KINDS = KINDS  # every kind is a target in turn
MIN_PIXELS = 120
MIN_VISIBLE = 0.6  # share of the target's silhouette not hidden by other objects, in both views
SENSOR_RANGE_M = (0.25, 3.86)


@dataclass(frozen=True)
class TrueSymmetry:
    """The rotations g of the object (object frame, about its centre) for which the goal image would look the
    same had the object made the motion M g instead of M: discrete ones, every turn about `axis` (with `flip`:
    also end-for-end), or all (ball)."""

    rotations: np.ndarray
    axis: np.ndarray | None = None
    flip: bool = False
    ball: bool = False

    @property
    def label(self) -> str:
        if self.ball:
            return "ball"
        if self.axis is not None:
            return "revolution+flip" if self.flip else "revolution"
        return "none" if len(self.rotations) == 1 else f"{len(self.rotations)} rotations"


@dataclass(frozen=True)
class RaycastPair:
    """One benchmark pair and its truth; the input fields match pipeline.grounding's GroundingInput."""

    rgb0: np.ndarray
    depth0: np.ndarray  # metric, NaN invalid
    mask0: np.ndarray
    rgb1: np.ndarray
    depth1: np.ndarray  # relative prediction
    depth1_kind: str
    mask1: np.ndarray
    intrinsics: CameraIntrinsics
    T_base_camera: np.ndarray
    T_motion_camera: np.ndarray  # true x_goal = T x_init, camera frame
    centre_camera: np.ndarray  # the object's centre (bounding box) at the initial pose, camera frame
    T_camera_object0: np.ndarray
    object_kind: str
    motion_kind: str
    symmetry: TrueSymmetry
    shape_symmetry: TrueSymmetry  # the shape's alone, whatever its print: no reported symmetry may go beyond it
    size_m: float
    seed: int
    index: int
    corruptions: dict = field(default_factory=dict)

    @property
    def object_name(self) -> str:
        return f"{self.object_kind}_{self.index}"


def shape_only_symmetry(shape: Shape) -> TrueSymmetry:
    """The turns the shape alone cannot show, as a TrueSymmetry (what a uniform print would give)."""
    s = shape.symmetry
    if s.ball:
        return TrueSymmetry(np.eye(3)[None], ball=True)
    if s.revolution:
        return TrueSymmetry(np.eye(3)[None], axis=np.array([0.0, 0.0, 1.0]), flip=s.flip)
    return TrueSymmetry(s.rotations)


def true_symmetry(shape: Shape, material: Material, seen: np.ndarray, rng: np.random.Generator) -> TrueSymmetry:
    """The shape's symmetries that the goal image cannot show: a rotation g counts when every surface point the
    goal view sees (seen (N, 3), object frame) has the colour of the point g brings there (motion M and M g give
    the same goal image). A texture the goal view does not see does not count; one it sees does."""
    s = shape.symmetry
    c = shape.centre
    base = material.colour(seen)

    def keeps(R: np.ndarray) -> bool:
        return bool(np.abs(material.colour(c + (seen - c) @ R) - base).max() < 0.02)  # colour at g^-1 p

    if s.ball:
        samples = Rotation.random(48, rng).as_matrix()
        kept = [R for R in samples if keeps(R)]
        if len(kept) == len(samples):
            return TrueSymmetry(np.eye(3)[None], ball=True)
        return TrueSymmetry(np.array([np.eye(3), *kept]))
    if s.revolution:
        turns = Rotation.from_rotvec(np.outer(np.radians(np.arange(5.0, 360.0, 5.0)), [0, 0, 1])).as_matrix()
        flips = [np.diag([1.0, -1.0, -1.0]) @ R for R in [np.eye(3), *turns]] if s.flip else []
        kept_turns = [R for R in turns if keeps(R)]
        kept_flips = [R for R in flips if keeps(R)]
        if len(kept_turns) == len(turns):
            return TrueSymmetry(np.eye(3)[None], axis=np.array([0.0, 0.0, 1.0]), flip=len(kept_flips) == len(flips) > 0)
        return TrueSymmetry(np.array([np.eye(3), *kept_turns, *kept_flips]))
    return TrueSymmetry(np.array([R for R in s.rotations if keeps(R)]))


def _camera(rng: np.random.Generator) -> tuple[CameraIntrinsics, np.ndarray, np.ndarray]:
    """Intrinsics, T_base_camera and the table point it looks at."""
    width, height = (640, 480) if rng.random() < 0.25 else (640, 360)
    hfov = math.radians(rng.uniform(60.0, 85.0))
    f = width / 2 / math.tan(hfov / 2)
    K = CameraIntrinsics(width, height, f, f * rng.uniform(0.995, 1.005), width / 2 - 0.5, height / 2 - 0.5)
    look = np.array([rng.uniform(0.45, 0.6), rng.uniform(-0.1, 0.1), 0.0])
    dist, el, az = rng.uniform(0.6, 1.0), math.radians(rng.uniform(35, 70)), math.radians(rng.uniform(-40, 40))
    eye = look + dist * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    z = (look - eye) / np.linalg.norm(look - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1) @ Rotation.from_euler("z", rng.uniform(-5, 5), degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, eye
    return K, T, look


def _light(rng: np.random.Generator) -> Light:
    el, az = math.radians(rng.uniform(30, 80)), rng.uniform(0, 2 * math.pi)
    d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    tint = np.array([1.0, 1.0, 1.0]) + rng.uniform(-0.08, 0.08, 3)
    return Light(d, rng.uniform(0.55, 0.9), rng.uniform(0.2, 0.45), tint)


def _perturbed(light: Light, rng: np.random.Generator) -> Light:
    """The editor re-renders the scene: the light a little elsewhere and a little stronger or weaker."""
    turn = Rotation.from_rotvec(math.radians(rng.uniform(0, 8)) * _unit(rng.normal(size=3))).as_matrix()
    d = turn @ light.direction
    d[2] = max(d[2], 0.3)
    return Light(
        _unit(d), light.intensity * rng.uniform(0.9, 1.1), light.ambient + rng.uniform(-0.04, 0.04), light.tint
    )


def _rest_pose(shape: Shape, rng: np.random.Generator) -> np.ndarray:
    """A stable resting orientation: a box on any face, a cylinder or bottle upright or lying, others upright."""
    R = np.eye(3)
    if shape.kind == "box":
        R = CUBE_ROTATIONS[rng.integers(24)]
    elif shape.kind in ("cylinder", "bottle") and rng.random() < 0.3:
        R = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    return Rotation.from_euler("z", rng.uniform(0, 360), degrees=True).as_matrix() @ R


def resting_pose(shape: Shape, R: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """T_world_object with rotation R, the object's centre above xy and its lowest point on the table."""
    T = np.eye(4)
    T[:3, :3] = R
    v = shape.mesh.vertices @ R.T
    c = shape.centre @ R.T
    T[:3, 3] = [xy[0] - c[0], xy[1] - c[1], -v[:, 2].min()]
    return T


def _footprint(shape: Shape, T: np.ndarray) -> tuple[np.ndarray, float]:
    """(centre xy, radius) of a circle holding the object's outline on the table."""
    v = shape.mesh.vertices @ T[:3, :3].T + T[:3, 3]
    c = 0.5 * (v[:, :2].min(axis=0) + v[:, :2].max(axis=0))
    return c, float(np.linalg.norm(v[:, :2] - c, axis=1).max())


def _free(shape: Shape, T: np.ndarray, others: list[Placed], look: np.ndarray) -> bool:
    c, r = _footprint(shape, T)
    if np.abs(c - look[:2]).max() > 0.3:
        return False
    for o in others:
        oc, orad = _footprint(o.shape, o.T_world_object)
        if np.linalg.norm(c - oc) < r + orad + 0.01:
            return False
    return True


def _goal_rotation(motion: str, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """(world rotation about the object's centre, shift length [m]) of a motion kind."""
    yaw = Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True)
    if motion == "turn":
        yaw = Rotation.from_euler("z", rng.choice([-1, 1]) * rng.uniform(20, 180), degrees=True)
        return yaw.as_matrix(), rng.uniform(0, 0.015)
    if motion == "tip":
        a = rng.uniform(0, 2 * math.pi)
        tilt = 90.0 if rng.random() < 0.5 else rng.uniform(20, 90)
        R_tilt = Rotation.from_rotvec(math.radians(tilt) * np.array([math.cos(a), math.sin(a), 0.0]))
        return (yaw * R_tilt).as_matrix(), rng.uniform(0, 0.4)
    return yaw.as_matrix(), rng.uniform(0.05, 0.4)


def _touches_border(mask: np.ndarray, margin: int = 3) -> bool:
    return bool(mask[:margin].any() or mask[-margin:].any() or mask[:, :margin].any() or mask[:, -margin:].any())


def make_pair(seed: int, index: int, max_tries: int = 60, without: frozenset[str] = frozenset()) -> RaycastPair:
    """Pair `index` of set `seed`; the target kind and motion kind cycle with the index, everything else is
    drawn. Draws again (same generator) until the target is visible enough in both views. `without`: corruptions
    (corrupt.CORRUPTIONS) drawn but not done, the pair otherwise the same."""
    if unknown := set(without) - set(CORRUPTIONS):
        raise ValueError(f"pairgen: unknown corruption(s) {sorted(unknown)}; known: {', '.join(CORRUPTIONS)}")
    rng = np.random.default_rng([seed, index])
    kind = TARGET_KINDS[index % len(TARGET_KINDS)]
    motion = "slide" if kind == "ball" else MOTION_KINDS[(index // len(TARGET_KINDS)) % len(MOTION_KINDS)]
    for _ in range(max_tries):
        pair = _attempt(rng, seed, index, kind, motion, frozenset(without))
        if pair is not None:
            return pair
    raise RuntimeError(f"pairgen: no usable pair {index} of seed {seed} ({kind}, {motion}) in {max_tries} draws")


def _attempt(
    rng: np.random.Generator, seed: int, index: int, kind: str, motion: str, without: frozenset[str]
) -> RaycastPair | None:
    K, T_bc, look = _camera(rng)
    table, light = table_material(rng), _light(rng)
    shape = make_shape(kind, rng)
    surface = shape.mesh.sample_surface(500, rng)
    target_material = random_material(rng, surface, shape.size_m)
    placed: list[Placed] = []
    xy = look[:2] + rng.uniform(-0.12, 0.12, 2)
    target = Placed(shape, target_material, resting_pose(shape, _rest_pose(shape, rng), xy))
    for _ in range(int(rng.integers(1, 4))):  # other objects that stay put
        s = make_shape(str(rng.choice(KINDS)), rng)
        T = resting_pose(s, _rest_pose(s, rng), look[:2] + rng.uniform(-0.25, 0.25, 2))
        if _free(s, T, [target, *placed], look):
            placed.append(Placed(s, random_material(rng, s.mesh.sample_surface(300, rng), s.size_m), T))
    R_motion, shift = _goal_rotation(motion, rng)
    heading = rng.uniform(0, 2 * math.pi)
    c0 = target.T_world_object[:3, :3] @ shape.centre + target.T_world_object[:3, 3]
    goal_xy = c0[:2] + shift * np.array([math.cos(heading), math.sin(heading)])
    T_goal = resting_pose(shape, R_motion @ target.T_world_object[:3, :3], goal_xy)
    if not _free(shape, T_goal, placed, look):
        return None
    alone0 = silhouette(K, T_bc, target)
    goal_target = Placed(shape, target_material, T_goal)
    alone1 = silhouette(K, T_bc, goal_target)
    if _touches_border(alone0) or _touches_border(alone1):
        return None
    r0 = render(K, T_bc, [target, *placed], table, light)
    m0 = r0.ids == 1
    if m0.sum() < MIN_PIXELS or m0.sum() < MIN_VISIBLE * alone0.sum():
        return None
    corruptions: dict = {}
    goal_light = _perturbed(light, rng)
    goal_material = target_material
    if rng.random() < 0.35:
        retextured = partially_retextured(target_material, rng, shape.centre)
        if "retexture" not in without:
            goal_material, corruptions["retextured"] = retextured, True
    r1 = render(K, T_bc, [Placed(shape, goal_material, T_goal), *placed], table, goal_light)
    m1 = r1.ids == 1
    if m1.sum() < MIN_PIXELS or m1.sum() < MIN_VISIBLE * alone1.sum():
        return None
    depth0 = sensor_depth(r0.depth, rng)
    depth0[(depth0 < SENSOR_RANGE_M[0]) | (depth0 > SENSOR_RANGE_M[1])] = np.nan
    rgb1, corruptions["editor"] = editor_drift(sensor_image(r1.rgb, rng), rng, "editor" in without)
    depth_kind = "disparity" if rng.random() < 0.5 else "depth"
    depth1, corruptions["depth_model"] = monocular_depth(r1.depth, depth_kind, rng, without)
    mask0, corruptions["mask0"] = segmenter_mask(m0, rng, "masks" in without)
    mask1, corruptions["mask1"] = segmenter_mask(m1, rng, "masks" in without)
    T_cb = np.linalg.inv(T_bc)
    T_motion_world = T_goal @ np.linalg.inv(target.T_world_object)
    surface = shape.mesh.sample_surface(4000, rng)
    seen = visible(T_bc, [goal_target, *placed], surface @ T_goal[:3, :3].T + T_goal[:3, 3])
    seen_in_goal = surface[seen]
    return RaycastPair(
        rgb0=sensor_image(r0.rgb, rng),
        depth0=depth0,
        mask0=mask0,
        rgb1=rgb1,
        depth1=depth1,
        depth1_kind=depth_kind,
        mask1=mask1,
        intrinsics=K,
        T_base_camera=T_bc,
        T_motion_camera=T_cb @ T_motion_world @ T_bc,
        centre_camera=(T_cb @ np.append(c0, 1.0))[:3],
        T_camera_object0=T_cb @ target.T_world_object,
        object_kind=kind,
        motion_kind=motion,
        symmetry=true_symmetry(shape, target_material, seen_in_goal, rng),
        shape_symmetry=shape_only_symmetry(shape),
        size_m=shape.size_m,
        seed=seed,
        index=index,
        corruptions=corruptions,
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)
