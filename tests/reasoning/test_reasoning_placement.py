"""Where the offline editor puts an object: a free, supported spot in reach and in view in the relation asked for,
or a refusal saying what stood in the way; and the instruction checked against the grammar before anything."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.reasoning.instruction import GRAMMAR, InstructionError, check_instruction
from pipeline.reasoning.offline_editor import OfflineEditor
from pipeline.reasoning.providers import ProviderError
from pipeline.reasoning.types import EditRequest

BLOCK = {"kind": "box", "size_m": [0.045, 0.045, 0.045]}


def capture(sim_profile_with, tmp_path, objects: list[dict], yaw_jitter_deg: float | None = None):
    """One frame (with T_base_camera) of a scene of these objects, placed exactly (turned by the scene's default
    yaw jitter unless given)."""
    from drivers.sim import SimCamera, SimWorld

    path = tmp_path / "scene.yaml"
    randomise = {"xy_jitter_m": 0.0} | ({} if yaw_jitter_deg is None else {"yaw_jitter_deg": yaw_jitter_deg})
    path.write_text(yaml.safe_dump({"name": "t", "objects": objects, "randomise": randomise}))
    profile = sim_profile_with({"sim": {"scene": str(path)}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=0) as camera:
        return camera.read().with_extrinsics(camera.T_base_camera)


def goal_in_base(frame, result, mask) -> np.ndarray:
    """Where the edit puts the centre of the masked object's seen points, in the base frame."""
    pts = frame.intrinsics.unproject_depth_image(frame.depth)[mask & np.isfinite(frame.depth)]
    T = frame.T_base_camera @ result.T_goal_init_camera
    return T[:3, :3] @ pts.mean(axis=0) + T[:3, 3]


def test_behind_takes_a_free_spot_when_straight_behind_is_taken(sim_profile_with, tmp_path):
    blocker = (0.345, 0.05)  # where "just behind the blue block" would be
    frame = capture(
        sim_profile_with,
        tmp_path,
        [
            {"name": "red", "color": "red", "xy_m": [0.50, -0.18], **BLOCK},
            {"name": "blue", "color": "blue", "xy_m": [0.45, 0.05], **BLOCK},
            {"name": "green", "color": "green", "xy_m": list(blocker), **BLOCK},
        ],
    )
    seg = OfflineSegmenter()
    request = EditRequest(
        frame.rgb, "put the red block behind the blue block", frame.depth, frame.intrinsics, frame.T_base_camera
    )
    result = OfflineEditor(seg).edit(request)
    goal = goal_in_base(frame, result, seg.segment(frame.rgb, "red block")[0].mask)
    assert goal[0] < 0.45 - 0.04  # behind: farther from the camera than the blue block
    for other in ((0.45, 0.05), blocker):
        assert np.hypot(*(goal[:2] - other)) > 0.045 + 0.02, f"goal {goal[:2]} on top of {other}"


def test_a_place_with_no_free_spot_is_refused_saying_why(sim_profile_with, tmp_path):
    frame = capture(
        sim_profile_with,
        tmp_path,
        [
            {"name": "red", "color": "red", "xy_m": [0.40, -0.15], **BLOCK},
            {"name": "blue", "color": "blue", "xy_m": [0.64, 0.05], **BLOCK},  # near the reach limit
        ],
    )
    editor = OfflineEditor(OfflineSegmenter())
    request = EditRequest(
        frame.rgb, "put the red block in front of the blue block", frame.depth, frame.intrinsics, frame.T_base_camera
    )
    with pytest.raises(ProviderError, match=r"no free spot in front of the blue block: 28 spots tried \(28 out of"):
        editor.edit(request)
    unknown_reach = EditRequest(frame.rgb, request.prompt, frame.depth, frame.intrinsics)  # no T_base_camera
    assert editor.edit(unknown_reach).T_goal_init_camera is not None


class _Crowded:
    """A table on which only the spots at the given turns off the relation's direction are free."""

    def __init__(self, free_turns_deg: set[float]) -> None:
        from pipeline.reasoning.placement import PlacementConfig
        from pipeline.reasoning.tabletop import Plane

        self.config, self.plane, self.free = PlacementConfig(), Plane(np.array([0.0, 0.0, 1.0]), 0.0), free_turns_deg
        self.tried: list[float] = []

    def problem(self, target, shift: np.ndarray) -> str | None:
        turn = round(float(np.degrees(np.arctan2(shift[1], shift[0]))))
        self.tried.append(turn)
        return None if turn in self.free else "too close to another object"


def _flat_block(centre: tuple[float, float]):
    from pipeline.reasoning.tabletop import Plane, footprint

    corners = np.array([[centre[0] + x, centre[1] + y, 0.0] for x in (-0.02, 0.02) for y in (-0.02, 0.02)])
    return footprint(corners, Plane(np.array([0.0, 0.0, 1.0]), 0.0))


def test_a_spot_off_the_relations_edge_is_taken_only_when_all_nearer_its_direction_are_taken():
    from pipeline.reasoning.placement import spot_beside

    reference, target = _flat_block((0.0, 0.0)), _flat_block((0.0, 0.0))  # the target moves from the reference
    direction = np.array([1.0, 0.0, 0.0])
    table = _Crowded({45, -30})
    shift, _ = spot_beside(table, target, reference, direction, "in front of the block")
    assert shift is not None and round(float(np.degrees(np.arctan2(shift[1], shift[0])))) == -30
    assert 45 not in table.tried  # straight on and 15-30 deg off come first, at every distance
    table = _Crowded({45})
    shift, _ = spot_beside(table, target, reference, direction, "in front of the block")
    assert round(float(np.degrees(np.arctan2(shift[1], shift[0])))) == 45
    assert set(table.tried[:20]) == {0, 15, -15, 30, -30}
    shift, why = spot_beside(_Crowded(set()), target, reference, direction, "in front of the block")
    assert shift is None and "28 spots tried (28 too close to another object)" in why


def test_check_instruction_shows_the_grammar():
    assert check_instruction("put the dark blue bottle next to the scale").relation == "next_to"
    for sentence in ("wipe the table", "push the red block by 80 cm", "put the red gizmo on the plate"):
        with pytest.raises(InstructionError) as e:
            check_instruction(sentence)
        assert GRAMMAR in str(e.value), sentence


def _push(sim_profile_with, tmp_path, red: dict, blue_xy: tuple[float, float], prompt: str):
    frame = capture(
        sim_profile_with,
        tmp_path,
        [
            {"name": "red", "color": "red", "xy_m": [0.42, 0.0], **red},
            {"name": "blue", "color": "blue", "xy_m": list(blue_xy), **BLOCK},
        ],
        yaw_jitter_deg=0.0,
    )
    seg = OfflineSegmenter()
    request = EditRequest(frame.rgb, prompt, frame.depth, frame.intrinsics, frame.T_base_camera)
    return frame, seg, request


def test_a_push_may_end_nearer_a_neighbour_than_its_radius_when_its_outline_stays_clear(sim_profile_with, tmp_path):
    # a slab long across the push ends with its near face 15 mm from a block: its disc would cover the block
    slab = {"kind": "box", "size_m": [0.10, 0.03, 0.04]}
    frame, seg, request = _push(sim_profile_with, tmp_path, slab, (0.42, 0.0825), "push the red block right by 3 cm")
    result = OfflineEditor(seg).edit(request)
    mask = seg.segment(frame.rgb, "red block")[0].mask
    seen = frame.intrinsics.unproject_depth_image(frame.depth)[mask & np.isfinite(frame.depth)].mean(axis=0)
    start = frame.T_base_camera[:3, :3] @ seen + frame.T_base_camera[:3, 3]
    np.testing.assert_allclose(goal_in_base(frame, result, mask) - start, [0.0, 0.03, 0.0], atol=0.002)
    nearer = EditRequest(
        frame.rgb, "push the red block right by 4 cm", frame.depth, frame.intrinsics, frame.T_base_camera
    )
    with pytest.raises(ProviderError, match="where it would end is too close to another object"):
        OfflineEditor(seg).edit(nearer)  # 5 mm from the block


def test_a_push_through_another_object_is_refused(sim_profile_with, tmp_path):
    # the block stands across the path; past it, the end itself is clear
    _frame, seg, request = _push(sim_profile_with, tmp_path, BLOCK, (0.42, 0.07), "push the red block right by 15 cm")
    with pytest.raises(ProviderError, match=r"another object stands in its way, \d cm along"):
        OfflineEditor(seg).edit(request)


def test_an_object_put_in_a_bowl_whose_walls_hide_its_floor_goes_down_to_the_floor_not_onto_the_rim(
    sim_profile_with, tmp_path
):
    # seen from the camera, no point of its floor shows over the front wall
    bowl = {"name": "bowl", "kind": "bowl", "color": "dark_pink", "radius_m": 0.068, "height_m": 0.089}
    frame = capture(
        sim_profile_with,
        tmp_path,
        [{"name": "cube", "color": "green", "xy_m": [0.38, -0.29], **BLOCK}, bowl | {"xy_m": [0.25, 0.18]}],
    )
    seg = OfflineSegmenter()
    request = EditRequest(
        frame.rgb, "put the green cube in the bowl", frame.depth, frame.intrinsics, frame.T_base_camera
    )
    result = OfflineEditor(seg).edit(request)
    mask = seg.segment(frame.rgb, "green cube")[0].mask
    pts = frame.intrinsics.unproject_depth_image(frame.depth)[mask & np.isfinite(frame.depth)]
    T = frame.T_base_camera @ result.T_goal_init_camera
    lowest = float(np.min(pts @ T[:3, :3].T + T[:3, 3], axis=0)[2])
    assert 0.0 < lowest < 0.03  # on the bowl's floor (8 mm up), released a little above it; the rim is at 89 mm
