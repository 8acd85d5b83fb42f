import numpy as np
import pytest

from drivers.types import CameraIntrinsics, RGBDFrame

K = CameraIntrinsics(width=640, height=480, fx=600.0, fy=590.0, cx=319.5, cy=241.0)


def random_points(rng, n=200):
    return np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.4, 0.4, n), rng.uniform(0.4, 3.0, n)])


def test_project_unproject_round_trip():
    rng = np.random.default_rng(0)
    P = random_points(rng)
    uv = K.project(P)
    np.testing.assert_allclose(K.unproject(uv, P[:, 2]), P, atol=1e-12)


def test_matrix_round_trip():
    again = CameraIntrinsics.from_matrix(K.K, K.width, K.height)
    assert again == K


def test_resize_keeps_projection_consistent():
    """A point projects to the same place in the resized image, in pixel-centre coordinates."""
    rng = np.random.default_rng(1)
    P = random_points(rng)
    small = K.resized(320, 240)
    uv, uv_small = K.project(P), small.project(P)
    np.testing.assert_allclose((uv + 0.5) * 0.5 - 0.5, uv_small, atol=1e-9)
    # the image corners map onto each other
    np.testing.assert_allclose(small.resized(640, 480).K, K.K, atol=1e-12)


def test_crop_shifts_principal_point():
    rng = np.random.default_rng(2)
    P = random_points(rng)
    crop = K.cropped(100, 50, 300, 200)
    np.testing.assert_allclose(crop.project(P), K.project(P) - [100, 50], atol=1e-9)
    with pytest.raises(ValueError, match="outside"):
        K.cropped(500, 0, 300, 100)


def test_unproject_depth_image_matches_pointwise():
    depth = np.full((480, 640), 2.0, np.float32)
    depth[0, 0] = np.nan
    pts = K.unproject_depth_image(depth)
    np.testing.assert_allclose(pts[10, 20], K.unproject(np.array([[20, 10]]), [2.0])[0])
    assert np.isnan(pts[0, 0]).all()


@pytest.mark.parametrize("fx", [0.0, -1.0, float("nan")])
def test_invalid_focal_length_rejected(fx):
    with pytest.raises(ValueError, match="focal"):
        CameraIntrinsics(640, 480, fx, 500.0, 320.0, 240.0)


def test_project_refuses_points_behind_camera():
    with pytest.raises(ValueError, match="in front"):
        K.project(np.array([[0.0, 0.0, -1.0]]))


def test_rgbd_frame_validates_types_and_invalid_depth():
    small = K.resized(64, 48)
    rgb = np.zeros((48, 64, 3), np.uint8)
    depth = np.ones((48, 64), np.float32)
    RGBDFrame(rgb, depth, small, 0.0, 1)
    with pytest.raises(ValueError, match="float32"):
        RGBDFrame(rgb, depth.astype(np.float64), small, 0.0, 1)
    bad = depth.copy()
    bad[0, 0] = 0.0
    with pytest.raises(ValueError, match="must be NaN"):
        RGBDFrame(rgb, bad, small, 0.0, 1)
    with pytest.raises(ValueError, match="uint8"):
        RGBDFrame(rgb.astype(np.float32), depth, small, 0.0, 1)
