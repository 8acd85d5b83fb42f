"""The views tell the grounded motion from its shape's twins (a print), or the turn is reported as not seen."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.seen_turns import read_turns, shape_turns
from pipeline.grounding.types import SeenSymmetry
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import make_view

K = CameraIntrinsics(80, 60, 80.0, 80.0, 39.5, 29.5)
OBJ = np.zeros((60, 80), bool)
OBJ[20:40, 30:50] = True
DEPTH = np.where(OBJ, 0.8, 1.0).astype(np.float32)
HALF = np.diag([-1.0, -1.0, 1.0])  # half a turn about the viewing axis


def _view(chroma: np.ndarray, slid_px: int = 0):
    """The tile with its print, slid `slid_px` pixels to the right in the image at the same depth."""
    mask, depth, chroma = (np.roll(a, slid_px, axis=1) for a in (OBJ, DEPTH, chroma))
    cloud = K.unproject_depth_image(depth)[mask]
    return make_view(cloud, chroma[mask], depth, mask, chroma, 0.004)


def _printed() -> np.ndarray:
    chroma = np.full((60, 80, 3), 1 / 3, np.float32)
    chroma[:, :40] = (0.5, 0.25, 0.25)  # the left half of the tile red
    return chroma


def _tile() -> SeenSymmetry:
    centre = K.unproject_depth_image(DEPTH)[OBJ].mean(axis=0)
    return SeenSymmetry("box", centre, rotations=np.array([np.eye(3), HALF]), shape_kind="box")


def test_the_print_turns_a_half_turned_twin_back_and_is_reported_read():
    shape = _tile()
    slide = np.array([0.8 * 12 / 80.0, 0.0, 0.0])  # 12 px at 0.8 m
    wrong = Similarity(1.0, HALF, shape.centre - HALF @ shape.centre + slide)  # turned half way: the shape cannot tell
    motion, seen, margin = read_turns(wrong, shape, _view(_printed()), _view(_printed(), slid_px=12), K, 0.004)
    np.testing.assert_allclose(motion.R, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(motion.apply(shape.centre[None])[0], shape.centre + slide, atol=1e-9)
    assert seen.kind == "none" and seen.shape_kind == "box" and margin > 0.1


def test_a_print_that_stays_put_in_the_image_tells_no_turn():
    """The tile left where it was: its print follows the views under the unturned twin exactly as the two images
    compared pixel for pixel do, as a shadow cast on a plate turned in place does (read 123 deg off before): the
    motion is still turned back, but the shape's turns are reported."""
    shape = _tile()
    wrong = Similarity(1.0, HALF, shape.centre - HALF @ shape.centre)
    motion, seen, margin = read_turns(wrong, shape, _view(_printed()), _view(_printed()), K, 0.004)
    np.testing.assert_allclose(motion.R, np.eye(3), atol=1e-9)
    assert seen.kind == "box" and seen.print_unread and margin < 0.1


def test_a_print_the_goal_lost_leaves_the_shapes_turns_reported():
    shape = _tile()
    plain = np.full((60, 80, 3), 1 / 3, np.float32)  # the editor painted the tile over
    still = Similarity(1.0, np.eye(3), np.zeros(3))
    motion, seen, margin = read_turns(still, shape, _view(_printed()), _view(plain), K, 0.004)
    np.testing.assert_allclose(motion.R, np.eye(3))
    assert seen.kind == "box" and seen.print_unread and len(seen.rotations) == 2 and margin < 0.1
    assert "print not told apart" in seen.label


def test_a_print_neither_twin_follows_tells_none_apart():
    shape = _tile()
    repainted = np.full((60, 80, 3), 1 / 3, np.float32)
    repainted[:, 30:40] = (0.25, 0.5, 0.25)  # another print: the tile as it was correlates -0.73, turned -0.18
    still = Similarity(1.0, np.eye(3), np.zeros(3))
    motion, seen, margin = read_turns(still, shape, _view(_printed()), _view(repainted), K, 0.004)
    assert seen.kind == "box" and seen.print_unread and margin < 0.1  # less bad is not told apart
    np.testing.assert_allclose(motion.R, np.eye(3))


def test_twins_that_all_put_the_object_elsewhere_leave_the_print_unread():
    """A centre read 10 cm off: the half-turned twin lands the tile beside its goal and is no rival, so the print
    was never compared; the motion goes with the shape's turns (it was reported read, and 120-150 deg off on raycast
    bottles)."""
    shape = _tile()
    shape = SeenSymmetry("box", shape.centre + np.array([0.1, 0.0, 0.0]), rotations=shape.rotations, shape_kind="box")
    still = Similarity(1.0, np.eye(3), np.zeros(3))
    motion, seen, margin = read_turns(still, shape, _view(_printed()), _view(_printed()), K, 0.004)
    np.testing.assert_allclose(motion.R, np.eye(3))
    assert seen.kind == "box" and seen.print_unread and margin < 0.1


def test_a_can_ends_alike_is_spun_and_flipped():
    can = SeenSymmetry("revolution_ends_alike", np.zeros(3), axis=np.array([0.0, 0.0, 1.0]))
    turns = shape_turns(can)
    assert len(turns) == 16 and np.allclose(turns[0], np.eye(3))
    assert all(abs(np.linalg.det(g) - 1) < 1e-9 for g in turns)
    flipped = [g for g in turns if g[2, 2] < -0.99]  # the axis end for end
    assert len(flipped) == 8


def _disc_view(K: CameraIntrinsics, spin_deg: float):
    """A flat printed disc facing the camera (a plate seen from above), its print spun by `spin_deg` in the image."""
    v, u = np.mgrid[0 : K.height, 0 : K.width]
    du, dv = u - K.cx, v - K.cy
    disc = du**2 + dv**2 < 40**2
    depth = np.where(disc, 0.8, 1.0).astype(np.float32)
    angle = (np.degrees(np.arctan2(dv, du)) - spin_deg) % 360
    chroma = np.full((K.height, K.width, 3), 1 / 3, np.float32)
    chroma[disc & (angle < 90)] = (0.5, 0.25, 0.25)  # a red quarter
    chroma[disc & (angle >= 180) & (angle < 230)] = (0.25, 0.25, 0.5)  # and a blue sector
    cloud = K.unproject_depth_image(depth)[disc]
    return make_view(cloud, chroma[disc], depth, disc, chroma, 0.003), cloud.mean(axis=0)


def test_a_printed_disc_spun_between_the_coarse_twins_is_found_to_a_few_degrees():
    disc_K = CameraIntrinsics(160, 120, 160.0, 160.0, 79.5, 59.5)
    view0, centre = _disc_view(disc_K, 0.0)
    view1, _ = _disc_view(disc_K, 30.0)  # spun 30 deg: between the 45 deg twins
    axis = np.array([0.0, 0.0, 1.0])
    plate = SeenSymmetry("revolution", centre, axis=axis, shape_kind="revolution")
    still = Similarity(1.0, np.eye(3), np.zeros(3))
    motion, seen, margin = read_turns(still, plate, view0, view1, disc_K, 0.004)
    spin = np.degrees(Rotation.from_matrix(motion.R).as_rotvec() @ axis)
    assert abs(spin - 30.0) < 3.0, spin
    np.testing.assert_allclose(motion.apply(centre[None])[0], centre, atol=1e-9)
    assert seen.kind == "none" and seen.shape_kind == "revolution" and margin > 0.1
