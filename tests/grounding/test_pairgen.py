"""bench/pairgen: the independent pair generator the grounding benchmark measures on (its own meshes, materials,
ray caster and corruptions), and the benchmark's scoring modulo symmetry."""

from __future__ import annotations

import ast
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))  # bench/ is not an installed package

from bench.pairgen.corrupt import editor_drift, monocular_depth, segmenter_mask  # noqa: E402
from bench.pairgen.generate import TrueSymmetry, make_pair, true_symmetry  # noqa: E402
from bench.pairgen.materials import Decal, Material  # noqa: E402
from bench.pairgen.render import Placed, visible  # noqa: E402
from bench.pairgen.scoring import rotation_error_deg  # noqa: E402
from bench.pairgen.shapes import CUBE_ROTATIONS, make_shape  # noqa: E402


def test_the_generator_shares_nothing_with_the_projects_renderer_or_scenes():
    for path in (REPO / "bench" / "pairgen").glob("*.py"):
        tree = ast.parse(path.read_text())
        names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        assert not [m for m in names if "mujoco" in m or m.startswith(("drivers.sim", "pipeline.grounding"))], path
        assert "configs/scenes" not in path.read_text(), path


def test_a_pair_is_reproducible_and_its_truth_fits_its_images():
    a, b = make_pair(7, 3), make_pair(7, 3)
    assert np.array_equal(a.rgb1, b.rgb1) and np.array_equal(a.mask0, b.mask0)
    np.testing.assert_array_equal(a.T_motion_camera, b.T_motion_camera)
    assert a.object_kind == "mug" and a.motion_kind == "slide"  # kinds cycle with the index
    K = a.intrinsics
    for centre, mask in (
        (a.centre_camera, a.mask0),
        (a.T_motion_camera[:3, :3] @ a.centre_camera + a.T_motion_camera[:3, 3], a.mask1),
    ):
        u, v = np.round(K.project(centre[None])[0]).astype(int)
        ys, xs = np.nonzero(mask)
        assert xs.min() - 5 <= u <= xs.max() + 5 and ys.min() - 5 <= v <= ys.max() + 5  # the centre is on it
    R = a.T_motion_camera[:3, :3]
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) == pytest.approx(1.0)
    assert a.depth1.dtype == np.float32 and np.isfinite(a.depth1).all()  # a model's prediction: every pixel


def test_corruptions_are_what_the_notes_describe():
    rng = np.random.default_rng(0)
    v, u = np.mgrid[0:120, 0:200]
    depth = 0.6 + 0.002 * v + np.where((u - 100) ** 2 + (v - 60) ** 2 < 400, -0.05, 0.0)  # a table and a bump
    for kind in ("depth", "disparity"):
        pred, done = monocular_depth(depth, kind, rng)
        x = depth if kind == "depth" else 1.0 / depth
        A = np.column_stack([x.ravel(), np.ones(x.size)])
        (s, b), *_ = np.linalg.lstsq(A, pred.ravel().astype(np.float64), rcond=None)
        rel = np.abs(A @ [s, b] - pred.ravel()) / np.abs(s * x.ravel())
        assert np.median(rel) < 0.03 and done["warp"] >= 0.01  # affine up to a slow warp and noise
        assert np.percentile(rel, 99.9) > 0.015  # but not exactly: the noise and the bled edges are there
    mask = np.zeros((120, 200), dtype=bool)
    mask[40:80, 60:140] = True
    for seed in range(10):
        m, _ = segmenter_mask(mask, np.random.default_rng(seed))
        assert m.any() and (m & mask).sum() / (m | mask).sum() > 0.7
    rgb = (rng.random((60, 80, 3)) * 255).astype(np.uint8)
    out, done = editor_drift(rgb, rng)
    assert out.shape == rgb.shape and out.dtype == np.uint8 and "gain" in done
    assert np.abs(out.astype(float) - rgb).mean() > 2.0


def test_a_corruption_left_out_is_drawn_but_not_done():
    v, u = np.mgrid[0:120, 0:200]
    depth = 0.6 + 0.002 * v + np.where((u - 100) ** 2 + (v - 60) ** 2 < 400, -0.05, 0.0)
    rng_all, rng_none = np.random.default_rng(4), np.random.default_rng(4)
    _, done_all = monocular_depth(depth, "disparity", rng_all)
    pred, done = monocular_depth(depth, "disparity", rng_none, frozenset({"bleed", "warp", "noise"}))
    assert rng_all.random() == rng_none.random()  # the same draws: what follows in a pair stays the same
    assert set(done_all) - set(done) == {"bleed_px", "warp", "noise"} and done["s"] == done_all["s"]
    np.testing.assert_allclose(pred, done["s"] / depth + done["b"], rtol=1e-5)  # exactly affine in disparity
    mask = np.zeros((120, 200), dtype=bool)
    mask[40:80, 60:140] = True
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    segmenter_mask(mask, rng_a)
    spared, _ = segmenter_mask(mask, rng_b, spared=True)
    assert np.array_equal(spared, mask) and rng_a.random() == rng_b.random()


def test_a_pair_without_a_corruption_is_the_same_pair_otherwise():
    full, clean_masks = make_pair(7, 3), make_pair(7, 3, without=frozenset({"masks"}))
    assert np.array_equal(full.rgb1, clean_masks.rgb1) and np.array_equal(full.depth1, clean_masks.depth1)
    np.testing.assert_array_equal(full.T_motion_camera, clean_masks.T_motion_camera)
    assert not np.array_equal(full.mask1, clean_masks.mask1) and clean_masks.corruptions["mask1"] == {}
    with pytest.raises(ValueError, match="unknown corruption"):
        make_pair(7, 3, without=frozenset({"blur"}))


def test_true_symmetry_is_what_the_goal_view_cannot_tell_apart():
    rng = np.random.default_rng(1)
    cube = make_shape("box", np.random.default_rng(0))
    while not np.allclose(*[cube.dims_m[k] for k in ("x", "y")]) or not np.isclose(cube.dims_m["x"], cube.dims_m["z"]):
        cube = make_shape("box", rng)
    plain = Material("uniform", (np.array([0.7, 0.2, 0.1]),))
    everywhere = cube.mesh.sample_surface(3000, rng)
    assert len(true_symmetry(cube, plain, everywhere, rng).rotations) == 24
    spot = cube.centre + np.array([0.25, 0.1, 0.5]) * np.array(list(cube.dims_m.values()))  # on top, off-centre
    sticker = Material("uniform", (np.array([0.7, 0.2, 0.1]),), decals=(Decal(spot, 0.01, np.array([0.1, 0.1, 0.9])),))
    assert len(true_symmetry(cube, sticker, everywhere, rng).rotations) == 1  # seen: it breaks every turn
    far_side = everywhere[np.linalg.norm(everywhere - spot, axis=1) > 0.5 * cube.size_m]
    assert len(true_symmetry(cube, sticker, far_side, rng).rotations) > 1  # not seen: some turns stay invisible


def test_only_what_the_camera_sees_is_visible():
    T_wc = np.eye(4)
    T_wc[:3, :3] = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # looking straight down
    T_wc[:3, 3] = [0, 0, 1.0]
    T_wo = np.eye(4)
    shape = make_shape("box", np.random.default_rng(3))
    placed = Placed(shape, Material("uniform", (np.ones(3) * 0.5,)), T_wo)
    half = np.array([0.0, 0.0, shape.dims_m["z"] / 2])
    top, bottom = shape.centre + half, shape.centre - 0.99 * half
    assert list(visible(T_wc, [placed], np.array([top, bottom]))) == [True, False]


def test_scoring_takes_out_the_true_symmetry_and_nothing_else():
    R0 = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    R_true = Rotation.from_euler("z", 40, degrees=True).as_matrix()
    G = R0 @ CUBE_ROTATIONS[5] @ R0.T  # a quarter turn of the cube, camera frame
    R_est = R_true @ G
    assert rotation_error_deg(R_est, R_true, R0, TrueSymmetry(CUBE_ROTATIONS)) == pytest.approx(0.0, abs=1e-4)
    assert rotation_error_deg(R_est, R_true, R0, TrueSymmetry(np.eye(3)[None])) == pytest.approx(90.0, abs=1e-6)
    small = R_true @ R0 @ Rotation.from_euler("x", 3, degrees=True).as_matrix() @ R0.T
    assert rotation_error_deg(small, R_true, R0, TrueSymmetry(CUBE_ROTATIONS)) == pytest.approx(3.0, abs=1e-6)
    axis = np.array([0.0, 0.0, 1.0])
    spin = R_true @ R0 @ Rotation.from_euler("z", 77, degrees=True).as_matrix() @ R0.T  # about the body's axis
    flip = R_true @ R0 @ Rotation.from_euler("x", 180, degrees=True).as_matrix() @ R0.T  # end for end
    bottle = TrueSymmetry(np.eye(3)[None], axis=axis)
    can = TrueSymmetry(np.eye(3)[None], axis=axis, flip=True)
    assert rotation_error_deg(spin, R_true, R0, bottle) == pytest.approx(0.0, abs=1e-4)
    assert rotation_error_deg(flip, R_true, R0, bottle) == pytest.approx(180.0, abs=1e-4)
    assert rotation_error_deg(flip, R_true, R0, can) == pytest.approx(0.0, abs=1e-4)
    assert math.isnan(rotation_error_deg(R_est, R_true, R0, TrueSymmetry(np.eye(3)[None], ball=True)))


def test_the_true_motions_twins_are_the_truth_modulo_its_symmetry():
    """bench/true_motion.py scores the best twin of the truth: each must be as right as the truth itself (same
    centre, zero rotation error modulo the symmetry) and, off the symmetry, different motions."""
    from bench.true_motion import true_twins

    R0 = Rotation.from_euler("xyz", [30, -20, 50], degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("zy", [70, 40], degrees=True).as_matrix()
    T[:3, 3] = [0.1, -0.05, 0.02]
    centre = np.array([0.05, 0.02, 0.6])
    goal_centre = T[:3, :3] @ centre + T[:3, 3]
    for truth, n in (
        (TrueSymmetry(CUBE_ROTATIONS), 24),
        (TrueSymmetry(np.eye(3)[None], axis=np.array([0.0, 0.0, 1.0]), flip=True), 72),
        (TrueSymmetry(np.eye(3)[None], ball=True), 2),
    ):
        twins = true_twins(T, truth, R0, centre)
        assert len(twins) == n
        for twin in twins:
            np.testing.assert_allclose(twin.apply(centre[None])[0], goal_centre, atol=1e-9)
            if not truth.ball:
                assert rotation_error_deg(twin.R, T[:3, :3], R0, truth) == pytest.approx(0.0, abs=1e-4)
        rotations = np.array([tw.R for tw in twins])
        assert len({tuple(np.round(R, 6).ravel()) for R in rotations}) == n  # no twin twice


def test_the_bench_tells_the_motion_kind_the_generator_made():
    """A turn in place far from the base's origin is a turn (its centre stays), not a slide."""
    from bench.grounding import motion_kind

    for index in (1, 9, 17):  # a cylinder slid, turned in place, tipped
        pair = make_pair(9001, index)
        assert motion_kind(pair.T_motion_camera, pair.T_base_camera, pair.centre_camera) == pair.motion_kind


def test_the_bench_puts_each_failure_down_to_the_score_or_the_search():
    """A failure where the truth ranks higher than the answer (what ground() chooses on) is the search's; one where it
    ranks no higher is the ranking's, whatever the refusal's score says; a refusal the truth shares is the score's."""
    from bench.grounding import failure_causes

    def record(
        ok: bool, truth: tuple[float, float], ranked: float, t_mm: float = 1.0, reason: str = "", answer=None
    ) -> dict:
        """truth: (its refusal score, what it ranks on); ranked: the answer's."""
        ours = {"ok": ok, "reason": reason, "t_mm": t_mm if ok else math.inf, "r_deg": 1.0 if ok else math.inf}
        ours |= {"agreement": 0.5, "ranked": ranked} if ok else {"refused_answer": answer}
        return {"ours": ours, "true_agreement": truth[0], "true_ranked": truth[1]}

    agreement = "the motion does not explain the images: view agreement 0.2 (need 0.4)"
    refused_answer = {"t_mm": 50.0, "r_deg": 30.0, "ranked": 0.5}
    records = [
        record(True, (0.9, 0.9), 0.8),  # right: no failure
        record(True, (0.9, 0.9), 0.8, t_mm=50.0),  # wrong, the truth ranks higher: the search missed it
        record(True, (0.2, 0.6), 0.5, t_mm=50.0),  # ... whatever its refusal score
        record(True, (0.9, 0.5), 0.8, t_mm=50.0),  # wrong, the truth ranks lower: the ranking prefers the wrong motion
        record(True, (0.9, 0.7), 0.7, t_mm=50.0),  # ... or no higher
        record(False, (0.2, 0.9), 0.0, reason=agreement, answer=refused_answer),  # the truth refused too
        record(False, (0.1, 0.1), 0.0, reason=agreement, answer=refused_answer),
        record(False, (0.6, 0.7), 0.0, reason=agreement, answer=refused_answer),  # the truth passes, ranks higher
        record(False, (0.6, 0.4), 0.0, reason=agreement, answer=refused_answer),  # it passes but ranks lower
        record(False, (0.6, 0.6), 0.0, reason="too few inliers: 3 of 90"),
    ]
    assert failure_causes(records, 0.4) == {
        "score_refuses_truth": 2,
        "score_prefers_wrong": 3,
        "search_missed": 3,
        "other_refusal": 1,
    }


def test_the_bench_counts_the_right_answers_the_agreement_refused():
    """A refusal by agreement is checked by the answer ground() gives with no threshold: right (within 20 mm and
    10 deg) or wrong, or none."""
    from bench.grounding import summarise

    refusal = {"ok": False, "reason": "the motion does not explain the images: view agreement 0.2 (need 0.3)"}
    refused = {"t_mm": math.inf, "r_deg": math.inf, "r_true_deg": math.inf, "ms": 1.0, "cpu_ms": 1.0}

    def record(answer: dict | None) -> dict:
        ours = refusal | refused | {"refused_answer": answer}
        paper = {"ok": True, "t_mm": 1.0, "r_deg": 1.0, "r_true_deg": 1.0, "ms": 1.0, "cpu_ms": 1.0}
        return {"ours": ours, "paper": paper, "true_agreement": 0.1, "true_ranked": 0.1}

    right = {"t_mm": 2.0, "r_deg": 1.0, "r_true_deg": 1.0, "symmetry": "none"}
    records = [record(right), record(right | {"t_mm": 50.0}), record(right | {"r_deg": 30.0}), record(None)]
    truth = summarise(records, 0.3)["true_motion"]
    assert truth["refused_by_agreement"] == 4
    assert truth["right_answers_refused"] == 1
