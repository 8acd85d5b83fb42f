"""Grounding inputs, settings and result."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from pydantic import Field

from drivers.config import StrictModel
from drivers.types import CameraIntrinsics
from pipeline.grounding.depth_align import DepthKind


class GroundingError(ValueError):
    """Unusable grounding input (wrong shape, type, empty mask...); the message names the input."""


class GroundingConfig(StrictModel):
    """Settings of our grounding (defaults tuned on bench/grounding.py)."""

    work_width_px: int | None = Field(
        default=None, ge=32, le=3840, description="ground on images resized to this width"
    )
    max_source_pixels: int = Field(
        default=1500, ge=10, le=100_000, description="object pixels of the initial image matched"
    )
    mutual: bool = Field(default=True, description="keep only mutual nearest neighbours")
    min_similarity: float = Field(default=0.6, ge=-1, le=1, description="cosine similarity below this is dropped")
    consistency_rel: float = Field(default=0.08, gt=0, description="pairwise distance tolerance / object size")
    min_consistency: float = Field(default=0.25, ge=0, le=1, description="share of matches a match must agree with")
    ransac_iterations: int = Field(default=2000, ge=10, le=100_000)
    inlier_rel: float = Field(default=0.06, gt=0, description="RANSAC inlier threshold / object size")
    inlier_min_m: float = Field(default=0.004, gt=0)
    hypotheses: int = Field(default=6, ge=1, le=100, description="RANSAC hypotheses verified against the images")
    sweep_hypotheses: int = Field(default=20, ge=0, le=500, description="geometric sweep hypotheses verified likewise")
    refine_top: int = Field(default=8, ge=1, le=100, description="hypotheses refined by ICP after a coarse view check")
    min_view_score: float = Field(
        default=0.3,
        ge=0,
        le=1,
        description="refuse below this geometric view agreement: 37 of 40 true motions of the raycast set (seed 9001) "
        "scored over it, a pan registered onto a tomato's mask 0.24",
    )
    min_hue_overlap: float = Field(
        default=0.04,
        ge=0,
        le=1,
        description="refuse a goal object whose hues share less than this with the initial one's (another object); "
        "true pairs share 0.08-1.0 on bench/grounding.py's sets",
    )
    min_inliers: int = Field(default=8, ge=3)
    min_inlier_ratio: float = Field(default=0.05, ge=0, le=1)
    scale_range: tuple[float, float] = Field(default=(0.9, 1.1), description="plausible similarity scale")
    min_spread_rel: float = Field(default=0.15, gt=0, description="inlier spread (2nd axis) / object size")
    icp: bool = True
    icp_voxel_m: float = Field(default=0.003, gt=0)
    icp_max_corr_rel: float = Field(default=0.08, gt=0, description="ICP correspondence distance / object size")
    max_depth_residual_m: float = Field(default=0.02, gt=0, description="refuse above this alignment residual")
    min_background_inliers: float = Field(default=0.5, ge=0, le=1)
    max_registration_residual_rel: float = Field(default=0.05, gt=0, description="inlier RMS / object size")
    seed: int = 0


@dataclass(frozen=True)
class SeenSymmetry:
    """The turns about `centre` (camera frame, as first seen) that the images cannot show (seen_symmetry.py):
    `kind` none, ball (every turn), revolution (every turn about `axis`), revolution_ends_alike (also end for
    end), box (`rotations`, (K, 3, 3), identity among them); `shape_kind` is the shape's own, before a print
    showing on the object made it none."""

    kind: str
    centre: np.ndarray
    axis: np.ndarray | None = None
    rotations: np.ndarray | None = None
    shape_kind: str = "none"
    print_unread: bool = False  # a print shows, but does not tell the motion from these twins (seen_turns.py)

    @property
    def label(self) -> str:
        unread = " (print not told apart)" if self.print_unread else ""
        if self.kind == "box" and self.rotations is not None:
            return f"box: {len(self.rotations)} turns{unread}"
        printed = " (printed)" if self.kind == "none" and self.shape_kind != "none" else ""
        return self.kind + printed + unread

    def moved(self, R: np.ndarray, t: np.ndarray) -> SeenSymmetry:
        """The same symmetry of the object carried by x' = R x + t (camera frame): seen from where it is now."""
        return replace(
            self,
            centre=R @ self.centre + t,
            axis=None if self.axis is None else R @ self.axis,
            rotations=None if self.rotations is None else R @ self.rotations @ R.T,
        )

    def box_turns_in(self, T_frame_camera: np.ndarray) -> np.ndarray | None:
        """A box's turns as (K, 4, 4) rigid motions of the object onto itself in another frame, or None."""
        if self.kind != "box" or self.rotations is None:
            return None
        H = np.tile(np.eye(4), (len(self.rotations), 1, 1))
        H[:, :3, :3] = self.rotations
        H[:, :3, 3] = self.centre - self.rotations @ self.centre
        return T_frame_camera @ H @ np.linalg.inv(T_frame_camera)


@dataclass(frozen=True)
class ObjectMotion:
    """Rigid motion of the target object: x_goal = R @ x_init + t (camera frame), plus how much to trust it.

    `scale` is the similarity scale the goal needed (1 = consistent sizes); `ok` False means refused, with
    `reason`; R and t are then identity/zero and must not be used.
    """

    ok: bool
    reason: str
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float = 1.0
    inliers: int = 0
    matches: int = 0
    residual_m: float = float("nan")
    depth_residual_m: float = float("nan")
    confidence: float = 0.0
    object_size_m: float = float("nan")
    T_base_camera: np.ndarray | None = None
    details: dict = field(default_factory=dict)
    symmetry: SeenSymmetry | None = None  # turns the images cannot show (accepted non-hinged motions)

    @property
    def T_camera(self) -> np.ndarray:
        """4x4 motion in the camera frame."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R, self.t
        return T

    @property
    def T_base(self) -> np.ndarray:
        """4x4 motion in the base frame: T_base_camera T_camera T_base_camera^-1 (needs the calibration)."""
        if self.T_base_camera is None:
            raise ValueError("ObjectMotion.T_base: no T_base_camera was given to ground()")
        return self.T_base_camera @ self.T_camera @ np.linalg.inv(self.T_base_camera)

    def to_json(self) -> dict:
        """The RESULT.json layout of `goalvla ground`."""
        out = {
            "ok": self.ok,
            "reason": self.reason,
            "R": self.R.tolist(),
            "t": self.t.tolist(),
            "scale": self.scale,
            "inliers": self.inliers,
            "residual_m": None if not np.isfinite(self.residual_m) else self.residual_m,
            "matches": self.matches,
            "confidence": self.confidence,
            "depth_residual_m": None if not np.isfinite(self.depth_residual_m) else self.depth_residual_m,
        }
        if self.T_base_camera is not None and self.ok:
            out["T_base_motion"] = self.T_base.tolist()
        return out


@dataclass(frozen=True)
class GroundingInput:
    """Initial view (metric depth) and goal view (relative depth prediction), with object masks; validated."""

    rgb0: np.ndarray
    depth0: np.ndarray
    mask0: np.ndarray
    rgb1: np.ndarray
    depth1: np.ndarray
    depth1_kind: DepthKind
    mask1: np.ndarray
    intrinsics: CameraIntrinsics
    anchor0: np.ndarray | None = None  # initial-view mask of the object the target is hinged to (stays put)
    depth1_measured: bool = False  # depth1 is a sensor's (after execution), not a model's: nothing to undo

    @classmethod
    def from_goal(cls, frame, goal) -> GroundingInput:
        """Stage 2's input from the capture (an RGBDFrame) and stage 1's GoalState (read by attribute, so the
        grounding package does not depend on the reasoning package)."""
        return cls(
            frame.rgb,
            frame.depth,
            goal.mask_init,
            goal.rgb_goal,
            goal.depth_goal.values,
            goal.depth_goal.kind,
            goal.mask_goal,
            frame.intrinsics,
            getattr(goal, "mask_anchor", None),
        )

    def __post_init__(self) -> None:
        h, w = self.intrinsics.height, self.intrinsics.width
        for key in ("rgb0", "rgb1"):
            a = getattr(self, key)
            if a.dtype != np.uint8 or a.shape != (h, w, 3):
                raise GroundingError(f"{key} must be uint8 ({h}, {w}, 3), got {a.dtype} {a.shape}")
        for key in ("depth0", "depth1"):
            a = getattr(self, key)
            if not np.issubdtype(a.dtype, np.floating) or a.shape != (h, w):
                raise GroundingError(f"{key} must be float ({h}, {w}), got {a.dtype} {a.shape}")
            if not (np.isfinite(a) & (a > 0 if key == "depth0" else True)).any():
                raise GroundingError(f"{key} has no valid value (all NaN{' or 0' if key == 'depth0' else ''})")
        for key in ("mask0", "mask1", "anchor0"):
            a = getattr(self, key)
            if a is None and key == "anchor0":
                continue
            if a.dtype != np.bool_ or a.shape != (h, w):
                raise GroundingError(f"{key} must be bool ({h}, {w}), got {a.dtype} {a.shape}")
            if not a.any():
                raise GroundingError(f"{key} is empty: no {'anchor' if key == 'anchor0' else 'object'} pixels")
        if self.depth1_kind not in ("depth", "disparity"):
            raise GroundingError(f"depth1_kind must be 'depth' or 'disparity', got {self.depth1_kind!r}")

    def resized(self, width: int) -> GroundingInput:
        """Both views at `width` pixels (aspect kept), intrinsics resized to match: colour is area-averaged,
        depth and masks take the nearest pixel so no value mixes foreground and background."""
        import cv2

        K = self.intrinsics
        height = max(1, round(K.height * width / K.width))
        size = (width, height)

        def near(a: np.ndarray) -> np.ndarray:
            return cv2.resize(a, size, interpolation=cv2.INTER_NEAREST)

        return GroundingInput(
            cv2.resize(self.rgb0, size, interpolation=cv2.INTER_AREA),
            near(self.depth0.astype(np.float32)),
            near(self.mask0.astype(np.uint8)).astype(bool),
            cv2.resize(self.rgb1, size, interpolation=cv2.INTER_AREA),
            near(self.depth1.astype(np.float32)),
            self.depth1_kind,
            near(self.mask1.astype(np.uint8)).astype(bool),
            K.resized(width, height),
            None if self.anchor0 is None else near(self.anchor0.astype(np.uint8)).astype(bool),
            self.depth1_measured,
        )
