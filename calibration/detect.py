"""Find the ChArUco board in a colour image and measure its pose in the camera frame (OpenCV 4.x aruco).

CharucoDetector finds the markers and interpolates the chessboard corners (sub-pixel); matchImagePoints pairs
them with the board's 3D corners; solvePnP (IPPE, then Levenberg-Marquardt refinement) gives T_camera_board.
The matched points are kept: the hand-eye refinement minimises their reprojection error over all views.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calibration.board import CharucoBoardSpec
from drivers.types import CameraIntrinsics

MIN_CORNERS = 8  # fewer corners give poor (and sometimes flipped) planar poses


@dataclass(frozen=True)
class BoardObservation:
    T_camera_board: np.ndarray  # (4, 4) [m]
    object_points: np.ndarray  # (N, 3) board-frame corners [m]
    image_points: np.ndarray  # (N, 2) pixels
    reprojection_px: float  # RMS over the corners


class BoardDetector:
    def __init__(self, spec: CharucoBoardSpec, intrinsics: CameraIntrinsics, distortion: np.ndarray | None = None):
        self.spec = spec
        self.board = spec.board()
        self.detector = cv2.aruco.CharucoDetector(self.board)
        self.K = intrinsics.K
        self.distortion = np.zeros(5) if distortion is None else np.asarray(distortion, dtype=np.float64)
        self.size = (intrinsics.width, intrinsics.height)

    def detect(self, rgb: np.ndarray, min_corners: int = MIN_CORNERS) -> BoardObservation | None:
        """The board's pose, or None when fewer than min_corners corners are found."""
        if rgb.shape[1::-1] != self.size:
            raise ValueError(
                f"image is {rgb.shape[1]}x{rgb.shape[0]}, intrinsics are for {self.size[0]}x{self.size[1]}"
            )
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        corners, ids, _, _ = self.detector.detectBoard(grey)
        if ids is None or len(ids) < min_corners:
            return None
        obj, img = self.board.matchImagePoints(corners, ids)
        obj, img = obj.reshape(-1, 3).astype(np.float64), img.reshape(-1, 2).astype(np.float64)
        ok, rvec, tvec = cv2.solvePnP(obj, img, self.K, self.distortion, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            return None
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, self.K, self.distortion, rvec, tvec)
        projected, _ = cv2.projectPoints(obj, rvec, tvec, self.K, self.distortion)
        rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img) ** 2, axis=1))))
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(rvec)[0]
        T[:3, 3] = tvec.ravel()
        return BoardObservation(T, obj, img, rms)
