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


def capture(sim_profile_with, tmp_path, objects: list[dict]):
    """One frame (with T_base_camera) of a scene of these objects, placed exactly."""
    from drivers.sim import SimCamera, SimWorld

    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump({"name": "t", "objects": objects, "randomise": {"xy_jitter_m": 0.0}}))
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
    with pytest.raises(ProviderError, match=r"no free spot in front of the blue block: 15 spots tried \(15 out of"):
        editor.edit(request)
    unknown_reach = EditRequest(frame.rgb, request.prompt, frame.depth, frame.intrinsics)  # no T_base_camera
    assert editor.edit(unknown_reach).T_goal_init_camera is not None


def test_check_instruction_shows_the_grammar():
    assert check_instruction("put the dark blue bottle next to the scale").relation == "next_to"
    for sentence in ("wipe the table", "push the red block by 80 cm", "put the red gizmo on the plate"):
        with pytest.raises(InstructionError) as e:
            check_instruction(sentence)
        assert GRAMMAR in str(e.value), sentence
