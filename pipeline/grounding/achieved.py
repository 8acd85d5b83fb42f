"""The motion an object really made between two metric captures from one camera pose, measured for verification.

It is measured the way grounding measured the goal's (a hinged part as a turn about its anchor), so the two can
be compared. A ball is the exception: no turn of it shows, and a registration of its uniform surface may refuse
or wander, so its fitted centre before and after is the whole measurement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import RGBDFrame
from pipeline.contact.sampling import estimate_normals
from pipeline.grounding.compare import (
    Symmetry,
    object_centre,
    object_symmetry,
    quarter_turn,
    spins_about,
    square_footprint_axis,
)
from pipeline.grounding.ground import ground
from pipeline.grounding.seen_symmetry import box_turns, on_its_base
from pipeline.grounding.types import GroundingConfig, GroundingInput, ObjectMotion
from pipeline.grounding.umeyama import Similarity
from pipeline.perception.features import FeatureExtractor

HINT_TWIST_DEG, HINT_TWIST_STEP_DEG = 30.0, 10.0  # the expected motion is tried turned this far, in these steps
HINT_SPIN_STEP_DEG = 30.0  # ... and a body of revolution's spun about its axis in these
NORMAL_RADIUS_M, VOXEL_M = 0.01, 0.003  # the seen points' normals, on 3 mm voxels, to find a box's faces


@dataclass(frozen=True)
class AchievedMotion:
    """x_after = R x_before + t of the object (camera frame), with what comparing it needs.

    registration: grounding's result between the captures (None for a ball, measured by its centre alone);
    symmetry: the turns the initial points' shape says no image can show (hidden_by_shape; None for a hinged part:
    its turn is judged).
    """

    R: np.ndarray
    t: np.ndarray
    centre_camera: np.ndarray  # the object's seen centre in the first capture
    symmetry: Symmetry | None
    registration: ObjectMotion | None

    @property
    def ok(self) -> bool:
        return self.registration is None or self.registration.ok

    @property
    def reason(self) -> str:
        return "" if self.registration is None else self.registration.reason


def _points(frame: RGBDFrame, mask: np.ndarray) -> np.ndarray:
    return frame.intrinsics.unproject_depth_image(frame.depth)[mask & np.isfinite(frame.depth)]


def hidden_by_shape(points: np.ndarray, up_camera: np.ndarray) -> Symmetry | None:
    """The turns the seen points' shape hides (camera frame): a ball's, a body of revolution's about its axis, a
    box's onto itself (seen_symmetry.box_turns), else a square footprint's quarter turns about the vertical
    `up_camera` (a small cube's faces can be too few to tell: square_footprint_axis); None when every turn shows."""
    symmetry = object_symmetry(points)
    if symmetry is not None and symmetry.ball:
        return symmetry
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    sparse = np.asarray(cloud.voxel_down_sample(VOXEL_M).points)  # a sensor's points are far denser than faces need
    normals = estimate_normals(sparse, NORMAL_RADIUS_M, np.zeros(3))
    if symmetry is not None:  # a plate's axis from its points alone may lie in it
        return on_its_base(sparse, normals, up_camera, symmetry)
    box = box_turns(sparse, normals)
    if box is not None:
        return Symmetry(box[0], None, turns=box[1])
    up = square_footprint_axis(points, up_camera)
    if up is None:
        return None
    return Symmetry(object_centre(points), None, turns=np.array([quarter_turn(up, k) for k in range(4)]))


def expected_hints(
    R: np.ndarray, t: np.ndarray, centre: np.ndarray, up: np.ndarray, symmetry: Symmetry | None
) -> list[Similarity]:
    """The expected motion (camera frame) and its near variants, as registration hints. A body of revolution:
    the motion spun about the object's own axis in HINT_SPIN_STEP_DEG steps (a spin no image shows, but it decides
    which side of the seen surface faces the camera: a lying bottle stood up by the goal's arbitrary spin may show
    the camera its unseen back, and the right motion then scores nothing). Anything else: the motion turned about
    the vertical `up` through where it puts the object's centre by up to HINT_TWIST_DEG (a turn often ends a few
    degrees off, beyond where ICP alone converges from the goal)."""
    if symmetry is not None and symmetry.axis is not None:
        pivot, axis, step = symmetry.centre, symmetry.axis, HINT_SPIN_STEP_DEG
        turns = spins_about(axis, step)
        moves = [(R @ S, R @ (pivot - S @ pivot) + t) for S in turns]  # spun about the axis first, then moved
    else:
        lands = R @ centre + t
        degrees = np.arange(-HINT_TWIST_DEG, HINT_TWIST_DEG + 1e-9, HINT_TWIST_STEP_DEG)
        turned = [Rotation.from_rotvec(np.radians(d) * up).as_matrix() @ R for d in degrees]
        moves = [(R_hint, lands - R_hint @ centre) for R_hint in turned]
    return [Similarity(1.0, R_hint, t_hint) for R_hint, t_hint in moves]


def measure_achieved(
    *,
    before: RGBDFrame,
    mask_before: np.ndarray,
    after: RGBDFrame,
    mask_after: np.ndarray,
    anchor_before: np.ndarray | None,
    features: FeatureExtractor,
    config: GroundingConfig,
    expected: tuple[np.ndarray, np.ndarray] | None = None,
) -> AchievedMotion:
    """The target's motion from `before` to `after` (same camera pose; masks of the target in each, and for a
    hinged part the initial mask of what it is hinged to). A refused registration comes back with ok False.

    `expected` (R, t): the motion the object should have made (the goal's, when verifying), a hint to the
    registration: polished on the captures and taken when it explains them as well as the best motion found, as it
    does when the object is where it should be up to a turn no view shows (a uniform box turned half way, a cube a
    quarter). A near-symmetric shape otherwise lets the registration settle on a twin tipped over or turned, which
    the comparison would then judge."""
    points = _points(before, mask_before)
    up_camera = before.T_base_camera[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    symmetry = None if anchor_before is not None else hidden_by_shape(points, up_camera)
    centre = object_centre(points)
    if symmetry is not None and symmetry.ball:
        seen_after = object_symmetry(_points(after, mask_after))
        if seen_after is not None and seen_after.axis is None:
            return AchievedMotion(np.eye(3), seen_after.centre - symmetry.centre, centre, symmetry, None)
    inp = GroundingInput(
        rgb0=before.rgb,
        depth0=before.depth,
        mask0=mask_before,
        rgb1=after.rgb,
        depth1=after.depth,
        depth1_kind="depth",
        mask1=mask_after,
        intrinsics=before.intrinsics,
        anchor0=anchor_before,
        depth1_measured=True,
    )
    hints = [] if expected is None else expected_hints(*expected, centre, up_camera, symmetry)
    motion = ground(inp, features, config, T_base_camera=before.T_base_camera, hints=hints)
    return AchievedMotion(motion.R, motion.t, centre, symmetry, motion)
