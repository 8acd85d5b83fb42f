"""Grounding's preparation of a generated goal: the editor's colour drift undone on the background, a model's noisy
depth smoothed inside the object (a sensor's left alone), and the error left in it measured."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.grounding.prepare import goal_depth_error, match_colours, pixel_noise, smooth_inside, smoothing_px


def test_an_editors_colour_drift_is_undone_on_the_object_too():
    rng = np.random.default_rng(0)
    reference = rng.integers(20, 235, (60, 80, 3)).astype(np.uint8)
    gain, offset = np.array([1.12, 0.9, 0.95]), np.array([-12.0, 8.0, 14.0])
    drifted = np.clip(reference * gain + offset, 0, 255).astype(np.uint8)
    obj = np.zeros((60, 80), bool)
    obj[20:40, 30:50] = True
    drifted[obj] = rng.integers(0, 255, (int(obj.sum()), 3))  # the object moved: its pixels say nothing
    undone = match_colours(drifted, reference, ~obj)
    error = np.abs(undone[~obj] - reference[~obj].astype(np.float32))
    assert float(np.median(error)) < 1.5 < float(np.median(np.abs(drifted[~obj] - reference[~obj].astype(float))))


@pytest.mark.parametrize(("noise_rel", "smoothed"), [(0.0005, False), (0.002, False), (0.01, True)])
def test_only_a_models_noise_is_smoothed(noise_rel, smoothed):
    rng = np.random.default_rng(1)
    v, _u = np.mgrid[0:120, 0:160]
    depth = (0.7 + 0.003 * v).astype(np.float32)
    noisy = (depth * (1 + noise_rel * rng.normal(size=depth.shape))).astype(np.float32)
    measured = pixel_noise(noisy, np.ones(depth.shape, bool))
    assert measured == pytest.approx(noise_rel, rel=0.35)
    sigma = smoothing_px(measured)
    assert (sigma > 0) == smoothed
    if smoothed:
        before = goal_depth_error(depth, noisy, np.ones(depth.shape, bool), 0.0)
        after = goal_depth_error(depth, noisy, np.ones(depth.shape, bool), sigma)
        assert after < 0.4 * before  # the error the comparison is judged by shrinks with the smoothing


def test_smoothing_inside_the_object_leaves_what_lies_behind_it_out():
    depth = np.full((40, 40), 1.0, np.float32)
    obj = np.zeros((40, 40), bool)
    obj[10:30, 10:30] = True
    depth[obj] = 0.8
    smooth = smooth_inside(depth, obj, 3.0)
    np.testing.assert_allclose(smooth[obj], 0.8, atol=1e-5)  # its edge is not pulled toward the table
    np.testing.assert_array_equal(smooth[~obj], depth[~obj])


def test_depth_agreement_is_no_finer_than_the_goal_depths_error():
    from drivers.types import CameraIntrinsics
    from pipeline.grounding.umeyama import Similarity
    from pipeline.grounding.verify import make_view, view_consistency

    K = CameraIntrinsics(80, 60, 80.0, 80.0, 39.5, 29.5)
    obj = np.zeros((60, 80), bool)
    obj[20:40, 30:50] = True
    depth0 = np.where(obj, 0.8, 1.0).astype(np.float32)
    depth1 = np.where(obj, 0.808, 1.0).astype(np.float32)  # the model put the object 8 mm further off
    chroma = np.full((60, 80, 3), 1 / 3, np.float32)

    def view(depth, sigma):
        cloud = K.unproject_depth_image(depth)[obj]
        return make_view(cloud, chroma[obj], depth, obj, chroma, 0.004, sigma)

    still = Similarity(1.0, np.eye(3), np.zeros(3))
    assert view_consistency(still, view(depth0, 0.0), view(depth1, 0.0), K, 0.004).geometry < 0.1
    assert view_consistency(still, view(depth0, 0.0), view(depth1, 0.005), K, 0.004).geometry > 0.9


def test_a_right_motion_whose_colours_an_editor_turned_still_agrees_and_colour_ranks_a_geometric_tie():
    """Geometry decides agreement (an editor's hue shift leaves a right motion its depth and silhouette); colour
    ranks motions that geometry cannot tell apart (a two-coloured block turned half way about its middle)."""
    from drivers.types import CameraIntrinsics
    from pipeline.grounding.umeyama import Similarity
    from pipeline.grounding.verify import make_view, view_consistency

    K = CameraIntrinsics(80, 60, 80.0, 80.0, 39.5, 29.5)
    obj = np.zeros((60, 80), bool)
    obj[20:40, 30:50] = True
    depth = np.where(obj, 0.8, 1.0).astype(np.float32)
    chroma = np.full((60, 80, 3), 1 / 3, np.float32)
    chroma[:, :40] = (0.5, 0.25, 0.25)  # its left half red
    recoloured = chroma[..., ::-1].copy()  # the goal's hue turned everywhere

    def view(colours):
        cloud = K.unproject_depth_image(depth)[obj]
        return make_view(cloud, colours[obj], depth, obj, colours, 0.004)

    still = Similarity(1.0, np.eye(3), np.zeros(3))
    middle = K.unproject_depth_image(depth)[obj].mean(axis=0)
    half = np.diag([-1.0, -1.0, 1.0])  # half a turn about the viewing axis through its middle
    turned = Similarity(1.0, half, middle - half @ middle)
    drifted = view_consistency(still, view(chroma), view(recoloured), K, 0.004)
    assert drifted.geometry > 0.9 and drifted.colour < 0.6
    right, twin = (view_consistency(m, view(chroma), view(chroma), K, 0.004) for m in (still, turned))
    assert right.geometry == pytest.approx(twin.geometry, abs=0.05)
    assert right.ranked > twin.ranked + 0.1


def test_a_one_coloured_table_fixes_an_offset_not_a_gain():
    """A table of one colour (sensor noise only) shows an editor's offset but cannot fix a gain: a least-squares gain
    on that narrow range sent a grey plate's colour far off. The fit leans to a gain of 1 there."""
    rng = np.random.default_rng(5)
    rgb0 = np.clip(rng.normal((120.0, 110.0, 100.0), 2.0, (60, 80, 3)), 0, 255)
    obj = np.zeros((60, 80), bool)
    obj[20:40, 30:50] = True
    rgb0[obj] = (60.0, 90.0, 200.0)
    rgb1 = np.clip(rng.normal((128.0, 104.0, 104.0), 2.0, (60, 80, 3)), 0, 255)  # the editor's offset, new noise
    rgb1[obj] = (68.0, 84.0, 204.0)
    undone = match_colours(rgb1, rgb0, ~obj)
    np.testing.assert_allclose(undone[obj].mean(axis=0), (60.0, 90.0, 200.0), atol=4.0)


def test_hues_tell_another_object_from_an_editors_drift_and_grey_from_nothing():
    from pipeline.grounding.prepare import hue_overlap

    obj = np.zeros((60, 80), bool)
    obj[20:40, 30:50] = True
    red, blue, grey = (np.zeros((60, 80, 3)) + c for c in ((200.0, 40.0, 40.0), (40.0, 40.0, 200.0), (120.0,) * 3))
    drifted = np.clip(red * (0.9, 1.1, 1.0) + 10.0, 0, 255)
    assert hue_overlap(red, obj, drifted, obj) > 0.9
    assert hue_overlap(red, obj, blue, obj) < 0.04
    assert hue_overlap(red, obj, grey, obj) is None


def test_two_reds_either_side_of_the_hue_circles_end_overlap():
    """A dark red of hue 177 (OpenCV's, of 180: 354 deg) and, after an editor's drift, 2 (4 deg): ten degrees apart
    across the circle's end, where whole bins shared nothing (overlap 0: raycast 606:70, a red plate, was refused as
    another object); an orange 36 deg on shares part, a blue nothing."""
    from pipeline.grounding.prepare import hue_overlap

    obj = np.zeros((60, 80), bool)
    obj[20:40, 30:50] = True
    magenta_red, orange_red, orange, blue = (
        np.zeros((60, 80, 3)) + c
        for c in ((140.0, 20.0, 32.0), (140.0, 26.0, 20.0), (200.0, 100.0, 0.0), (40, 40, 200))
    )
    assert hue_overlap(magenta_red, obj, orange_red, obj) > 0.5
    assert hue_overlap(magenta_red, obj, orange, obj) < 0.5
    assert hue_overlap(magenta_red, obj, blue, obj) == 0.0
