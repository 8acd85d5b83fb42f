"""Dense features: chunked matching, bilinear upsampling, the DINOv2 backend from a tiny local model, and the
offline backend's invariance to in-plane rotation."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.grounding.matching import match_pixels
from pipeline.perception.descriptors import normalise_rows, sample_bilinear
from pipeline.perception.features import best_matches, make_feature_extractor


def test_chunked_matches_equal_brute_force():
    rng = np.random.default_rng(0)
    src, dst = normalise_rows(rng.normal(size=(300, 16))), normalise_rows(rng.normal(size=(500, 16)))
    idx, sim = best_matches(src, dst, chunk=37)
    full = src @ dst.T
    np.testing.assert_array_equal(idx, full.argmax(axis=1))
    np.testing.assert_allclose(sim, full.max(axis=1), rtol=1e-5)


class _Lookup:
    """Features of a test without images: the "image" is the descriptor table, a pixel's u its row."""

    name = "lookup"

    def extract(self, table, pixels, points=None):
        return table[np.asarray(pixels)[:, 0]]


def _rows(n: int) -> np.ndarray:
    return np.c_[np.arange(n), np.zeros(n, int)]


def test_mutual_matches_are_those_whose_goal_pixel_chooses_them_back():
    rng = np.random.default_rng(1)
    src, dst = normalise_rows(rng.normal(size=(200, 8))), normalise_rows(rng.normal(size=(900, 8)))
    full = src @ dst.T
    forward, back = full.argmax(axis=1), full.argmax(axis=0)
    mutual = np.flatnonzero(back[forward] == np.arange(200))
    assert 0 < len(mutual) < 200
    m = match_pixels(_Lookup(), src, _rows(200), dst, _rows(900), mutual=True)
    np.testing.assert_array_equal(m.src_px[:, 0], mutual)
    np.testing.assert_array_equal(m.dst_px[:, 0], forward[mutual])


def test_bilinear_sampling_hits_cell_centres():
    grid = np.zeros((2, 3, 3), np.float32)
    for i in range(2):
        for j in range(3):
            grid[i, j, (i * 3 + j) % 3] = 1.0 + i
    # image 30 x 20: cell (i, j) centre at ((j + 0.5) * 10 - 0.5, (i + 0.5) * 10 - 0.5)
    out = sample_bilinear(grid, np.array([[4.5, 4.5], [24.5, 14.5]]), (30, 20))
    np.testing.assert_allclose(out[0], normalise_rows(grid[0, 0][None])[0], atol=1e-6)
    np.testing.assert_allclose(out[1], normalise_rows(grid[1, 2][None])[0], atol=1e-6)


def test_dinov2_backend_loads_a_local_model(tmp_path):
    from transformers import Dinov2Config, Dinov2Model

    cfg = Dinov2Config(
        hidden_size=32, num_hidden_layers=2, num_attention_heads=2, intermediate_size=64, patch_size=14, image_size=56
    )
    Dinov2Model(cfg).save_pretrained(tmp_path)
    features = make_feature_extractor("dinov2", model_id=str(tmp_path), short_side_px=56)
    rgb = np.random.default_rng(1).integers(0, 255, (60, 100, 3), dtype=np.uint8)
    grid = features.patch_grid(rgb)
    assert grid.shape == (4, 7, 32)  # 56 x 98 (multiples of 14, aspect kept)
    px = np.array([[0, 0], [99, 59], [50, 30]])
    f = features.extract(rgb, px)
    assert f.shape == (3, 32)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 1.0, rtol=1e-5)
    # a pixel at the centre of patch cell (0, 0) gets exactly that cell's feature
    centre = np.array([[(0.5 * 100 / 7) - 0.5, (0.5 * 60 / 4) - 0.5]])
    np.testing.assert_allclose(features.extract(rgb, centre)[0], normalise_rows(grid[0, 0][None])[0], atol=1e-5)


def test_unknown_backend_is_named():
    with pytest.raises(ValueError, match="unknown feature backend 'sift'"):
        make_feature_extractor("sift")


def test_offline_features_survive_an_in_plane_turn():
    """Ring colours are rotation invariant: a pixel keeps its best match when the image turns 90 degrees."""
    rng = np.random.default_rng(2)
    rgb = (rng.integers(0, 4, (12, 12, 3)) * 80).astype(np.uint8).repeat(8, 0).repeat(8, 1)
    rot = np.ascontiguousarray(np.rot90(rgb))  # (u, v) -> (v, W - 1 - u)
    features = make_feature_extractor("offline", geometry_weight=0.0, focal_px=400.0)
    src = np.argwhere(np.ones((96, 96), bool))[::97][:, ::-1]
    src = src[(src.min(axis=1) > 20) & (src.max(axis=1) < 75)]
    dst_all = np.argwhere(np.ones((96, 96), bool))[:, ::-1]
    idx, _ = best_matches(features.extract(rgb, src), features.extract(rot, dst_all))
    expected = np.stack([src[:, 1], 95 - src[:, 0]], axis=1)
    hit = np.linalg.norm(dst_all[idx] - expected, axis=1) <= 8
    assert hit.mean() > 0.6


def test_offline_surface_descriptors_follow_the_surface_not_the_pose():
    """The geometric block (FPFH) describes the surface round a pixel whatever its pose: the same pixels of a point
    map turned and shifted keep their descriptors, and a crease is told from a plane."""
    from scipy.spatial.transform import Rotation

    v, u = np.mgrid[0:80, 0:80].astype(float)
    points = np.stack([(u - 40) * 0.002, (v - 40) * 0.002, np.full(u.shape, 0.5)], axis=-1)
    points[..., 2] -= np.clip(points[..., 0], 0.0, None)  # a crease at column 40: flat, then sloping at 45 deg
    R = Rotation.from_euler("xy", [25, -15], degrees=True).as_matrix()
    moved = points @ R.T + np.array([0.03, -0.02, 0.1])
    pixels = np.array([[10, 40], [20, 8], [40, 40], [62, 40]])  # (u, v): flat, flat, the crease, the slope
    features = make_feature_extractor("offline", colour_weight=0.0, ring_weight=0.0)
    grey = np.full((80, 80, 3), 128, np.uint8)
    before, after = features.extract(grey, pixels, points), features.extract(grey, pixels, moved)
    assert np.all(np.einsum("ij,ij->i", before, after) > 0.99)
    assert float(before[0] @ before[1]) > 0.95 and float(before[0] @ before[3]) > 0.95  # planes look alike
    assert float(before[0] @ before[2]) < 0.8  # a crease does not
