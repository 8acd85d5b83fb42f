"""Board definition and printable scale, detection, and the hand-eye solve on synthetic views (exact, noisy,
degenerate), the quality bar and the stored result."""

from __future__ import annotations

import datetime as dt

import cv2
import numpy as np
import pytest
from PIL import Image
from scipy.spatial.transform import Rotation

from calibration.board import BoardError, CharucoBoardSpec, load_board, write_printable
from calibration.config import HandEyePlanConfig
from calibration.detect import BoardDetector, BoardObservation
from calibration.handeye import HandEyeError, rotation_diversity_deg, solve_hand_eye
from calibration.poses import board_centre
from calibration.session import judge
from calibration.store import load_calibration, save_calibration
from drivers.types import CameraIntrinsics

BOARD = load_board("configs/boards/charuco_8x6_30mm.yaml")
K = CameraIntrinsics(1280, 720, 760.0, 760.0, 639.5, 359.5)


def pose(rotvec, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def test_printable_file_is_true_scale(tmp_path):
    for suffix in (".png", ".pdf"):
        out = tmp_path / f"board{suffix}"
        width, height = write_printable(BOARD, out, dpi=300)
        assert out.stat().st_size > 1000
    img = Image.open(tmp_path / "board.png")
    dpi = img.info["dpi"][0]
    assert img.size == (width, height)
    assert width / dpi * 25.4 == pytest.approx(240 + 20, abs=0.2)  # board + 2 x 10 mm margin, in mm
    pdf = (tmp_path / "board.pdf").read_bytes()
    assert b"/MediaBox [ 0 0 737.00" in pdf  # 260 mm wide in points (72 per inch)


def test_board_definition_errors(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("squares_x: 8\nsquares_y: 6\nsquare_length_m: 0.03\nmarker_length_m: 0.04\n")
    with pytest.raises(BoardError, match=r"marker_length_m 0\.04 must be below square_length_m"):
        load_board(bad)
    with pytest.raises(ValueError, match="unknown ArUco dictionary"):
        CharucoBoardSpec(squares_x=5, squares_y=4, square_length_m=0.03, marker_length_m=0.02, dictionary="NOPE")
    with pytest.raises(BoardError, match=r"as \.png or \.pdf"):
        write_printable(BOARD, tmp_path / "board.svg")


def render_view(T_camera_board: np.ndarray) -> np.ndarray:
    """Warp the board image into a 1280x720 view with a homography (planar board, pinhole camera)."""
    px = 80
    img = BOARD.image(px)
    scale = BOARD.square_length_m / px  # metres per board-image pixel
    S = np.array([[scale, 0, -0.5 * scale], [0, scale, -0.5 * scale], [0, 0, 1]])  # pixel centres
    H = K.K @ np.column_stack([T_camera_board[:3, 0], T_camera_board[:3, 1], T_camera_board[:3, 3]]) @ S
    warped = cv2.warpPerspective(img, H, (K.width, K.height), flags=cv2.INTER_AREA, borderValue=200)
    return np.repeat(warped[..., None], 3, axis=2)


def test_detection_measures_the_board_pose():
    T_true = pose([0.3, -0.2, 0.1], [-0.1, -0.05, 0.7])
    obs = BoardDetector(BOARD, K).detect(render_view(T_true))
    assert obs is not None and len(obs.image_points) >= 30 and obs.reprojection_px < 0.5
    assert np.linalg.norm(obs.T_camera_board[:3, 3] - T_true[:3, 3]) < 0.002
    assert Rotation.from_matrix(obs.T_camera_board[:3, :3].T @ T_true[:3, :3]).magnitude() < np.radians(0.3)
    assert BoardDetector(BOARD, K).detect(np.full((720, 1280, 3), 128, np.uint8)) is None
    with pytest.raises(ValueError, match="intrinsics are for 1280x720"):
        BoardDetector(BOARD, K).detect(np.zeros((10, 10, 3), np.uint8))


def synthetic_views(mode, n, rng, noise_px=0.0, rotate=True):
    """Flange poses and board observations consistent with a known X (and Y), projected through K."""
    X = pose([0.1, -2.2, 0.3], [1.1, 0.05, 0.8]) if mode == "eye_to_hand" else pose([0.2, 0, 0.05], [0, 0.1, 0.05])
    Y = pose([0.0, 2.5, 0.0], [0.1, -0.1, 0.1]) if mode == "eye_to_hand" else pose([np.pi, 0, 0], [0.3, 0.1, 0.0])
    obj = np.array([[i * 0.03, j * 0.03, 0.0] for i in range(1, 8) for j in range(1, 6)])
    A, views = [], []
    while len(A) < n:
        rv = rng.normal(0, 0.3, 3) if rotate else np.array([0.0, 0.0, rng.normal(0, 0.5)])
        if mode == "eye_to_hand":
            R = Rotation.from_rotvec(rv) * Rotation.from_rotvec([0, 2.3, 0])
            a = pose(R.as_rotvec(), np.add(rng.uniform(-0.1, 0.1, 3), [0.35, 0, 0.35]))
            B = np.linalg.inv(X) @ a @ Y
        else:
            a = pose(
                (Rotation.from_rotvec(rv) * Rotation.from_rotvec([np.pi, 0, 0])).as_rotvec(),
                np.add(rng.uniform(-0.08, 0.08, 3), [0.4, 0.1, 0.45]),
            )
            B = np.linalg.inv(X) @ np.linalg.inv(a) @ Y
        cam = obj @ B[:3, :3].T + B[:3, 3]
        if np.any(cam[:, 2] < 0.1):
            continue
        uv = K.project(cam) + rng.normal(0, noise_px, (len(obj), 2))
        if np.any(uv < 0) or np.any(uv[:, 0] > 1279) or np.any(uv[:, 1] > 719):
            continue
        _ok, rvec, tvec = cv2.solvePnP(obj, uv, K.K, None, flags=cv2.SOLVEPNP_IPPE)
        Bm = pose(rvec.ravel(), tvec.ravel())
        A.append(a)
        views.append(BoardObservation(Bm, obj, uv, 0.0))
    return X, A, views


@pytest.mark.parametrize("mode", ["eye_to_hand", "eye_in_hand"])
def test_exact_views_give_the_exact_answer(mode):
    X, A, views = synthetic_views(mode, 10, np.random.default_rng(1))
    result = solve_hand_eye(mode, A, views, K.K, board_centre(BOARD))
    assert np.allclose(result.best.X, X, atol=1e-5)
    assert result.median_mm < 0.01
    assert {c.method for c in result.candidates} >= {"tsai", "park", "horaud", "andreff", "daniilidis"}


def test_noisy_views_keep_the_most_consistent_and_refinement_helps():
    X, A, views = synthetic_views("eye_to_hand", 15, np.random.default_rng(2), noise_px=0.3)
    result = solve_hand_eye("eye_to_hand", A, views, K.K, board_centre(BOARD))
    assert result.best.score == min(c.score for c in result.candidates)
    E = np.linalg.inv(X) @ result.best.X
    assert np.linalg.norm(E[:3, 3]) < 0.003
    assert Rotation.from_matrix(E[:3, :3]).magnitude() < np.radians(0.2)


def test_judge_refuses_poor_or_degenerate_data():
    cfg = HandEyePlanConfig(min_views=12, max_residual_mm=1.0)
    _X, A, views = synthetic_views("eye_to_hand", 10, np.random.default_rng(3), noise_px=3.0, rotate=False)
    outcome = judge("eye_to_hand", A, views, K.K, BOARD, cfg)
    text = "; ".join(outcome.problems)
    assert "only 10 views" in text and "rotate too little" in text and "median view residual" in text
    assert rotation_diversity_deg(A) < 8.0
    with pytest.raises(HandEyeError, match="at least 3 views"):
        solve_hand_eye("eye_to_hand", A[:2], views[:2], K.K, board_centre(BOARD))


def test_good_result_is_stored_with_date_and_quality(tmp_path):
    _X, A, views = synthetic_views("eye_in_hand", 14, np.random.default_rng(4), noise_px=0.1)
    outcome = judge("eye_in_hand", A, views, K.K, BOARD, HandEyePlanConfig())
    assert outcome.problems == []
    path = tmp_path / "cal.yaml"
    save_calibration(outcome.calibration, path)
    loaded = load_calibration(path)
    assert loaded.mode == "eye_in_hand" and loaded.poses == 14
    assert np.allclose(loaded.matrix, outcome.result.best.X)
    assert loaded.residual_mm == pytest.approx(outcome.result.median_mm)
    assert loaded.age_days(dt.datetime.now(dt.UTC)) < 0.01
