"""Offline grammar, segmenter and editor on the simulated tabletop (ground truth is used only to check them)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.perception.depth import DepthEstimationError, OfflineDepthEstimator
from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.reasoning.instruction import GRAMMAR, InstructionError, parse_instruction
from pipeline.reasoning.offline_editor import OfflineEditor
from pipeline.reasoning.providers import ProviderError
from pipeline.reasoning.types import EditRequest


@pytest.mark.parametrize(
    ("sentence", "action", "target", "relation", "reference"),
    [
        ("Put the red block on the white plate.", "place", "red block", "on", "white plate"),
        ("place the red block onto the plate", "place", "red block", "on", "plate"),
        ("move the blue block to the left of the green cylinder", "place", "blue block", "left_of", "green cylinder"),
        ("put the red cube in front of the blue block", "place", "red box", "in_front_of", "blue block"),
        ("put the red block into the pan", "place", "red block", "in", "pan"),
        ("move the green can behind the red block", "place", "green can", "behind", "red block"),
        ("place the red block next to the green cylinder", "place", "red block", "next_to", "green cylinder"),
    ],
)
def test_grammar_place(sentence, action, target, relation, reference):
    instr = parse_instruction(sentence)
    assert (instr.action, instr.relation) == (action, relation)
    assert instr.target.split()[0] == target.split()[0] and instr.reference.split()[-1] == reference.split()[-1]
    assert parse_instruction(instr.canonical()) == instr


def test_grammar_rotate_push_stand_close():
    r = parse_instruction("rotate the blue block by 30 degrees clockwise")
    assert r.action == "rotate" and r.angle_deg == -30.0
    assert parse_instruction("turn the blue block 45 deg").angle_deg == 45.0
    p = parse_instruction("push the red block left by 8 cm")
    assert (p.direction, p.distance_m) == ("left", pytest.approx(0.08))
    assert parse_instruction("push the pan").distance_m == pytest.approx(0.10)
    assert parse_instruction("stand the green bottle up").action == "stand_up"
    assert parse_instruction("stand up the green bottle").target == "green bottle"
    assert parse_instruction("close the yellow chest").action == "close"
    for text in ("rotate the blue block by 30 degrees clockwise", "push the red block left by 8 cm"):
        instr = parse_instruction(text)
        assert parse_instruction(instr.canonical()) == instr


@pytest.mark.parametrize("bad", ["fly the red block away", "put the red gizmo on the plate", "push the block by 2 m"])
def test_grammar_errors_name_the_problem(bad):
    with pytest.raises(InstructionError) as e:
        parse_instruction(bad)
    assert GRAMMAR.splitlines()[0] in str(e.value) or "push distance" in str(e.value)


@pytest.mark.parametrize(
    ("phrase", "name"),
    [
        ("the red block", "red_block"),
        ("blue block", "blue_block"),
        ("green cylinder", "green_cylinder"),
        ("white plate", "white_plate"),
        ("the plate", "white_plate"),
        ("the cylinder", "green_cylinder"),
    ],
)
def test_offline_segmenter_matches_ground_truth(sim_view, phrase, name):
    frame, masks, _ = sim_view
    found = OfflineSegmenter().segment(frame.rgb, phrase)
    gt = masks[name]
    iou = (found[0].mask & gt).sum() / (found[0].mask | gt).sum()
    assert iou > 0.85, f"{phrase}: IoU {iou:.2f}"
    assert found[0].mask.shape == frame.rgb.shape[:2]


def test_offline_segmenter_absent_colour_gives_nothing(sim_view):
    frame, _, _ = sim_view
    assert OfflineSegmenter().segment(frame.rgb, "the purple block") == []
    assert OfflineSegmenter().segment(np.zeros((40, 60, 3), np.uint8), "red block") == []


def test_editor_puts_the_block_on_the_plate_with_perspective(sim_view):
    frame, masks, world = sim_view
    seg, registry = OfflineSegmenter(), OfflineDepthEstimator()
    result = OfflineEditor(seg, registry).edit(
        EditRequest(frame.rgb, "put the red block on the white plate", frame.depth, frame.intrinsics)
    )
    T_bc = world.T_world_camera
    T_motion_base = T_bc @ result.T_goal_init_camera @ np.linalg.inv(T_bc)
    block, plate = world.object_pose("red_block")[:3, 3], world.object_pose("white_plate")[:3, 3]
    moved = T_motion_base[:3, :3] @ block + T_motion_base[:3, 3]
    assert np.linalg.norm(moved[:2] - plate[:2]) < 0.03  # centred on the plate (footprint estimate from depth)
    assert 0.010 < moved[2] - block[2] < 0.025  # lifted by the plate's height (15 mm)
    np.testing.assert_allclose(result.T_goal_init_camera[:3, :3], np.eye(3), atol=1e-9)
    # the block is gone from where it was and present once at the plate
    assert (seg.segment(result.rgb, "red block")[0].mask & masks["red_block"]).sum() == 0
    assert len(seg.segment(result.rgb, "red block")) == 1
    # the goal depth is registered, normalised disparity (nearer = larger)
    depth = registry.estimate(result.rgb)
    assert depth.kind == "disparity" and depth.values.shape == frame.depth.shape
    assert depth.values.min() >= 0.0 and depth.values.max() <= 1.0
    with pytest.raises(DepthEstimationError):
        registry.estimate(frame.rgb)


def test_editor_moving_nearer_enlarges_the_object(sim_view):
    frame, _, _ = sim_view
    seg = OfflineSegmenter()
    result = OfflineEditor(seg).edit(
        EditRequest(frame.rgb, "push the blue block backward by 12 cm", frame.depth, frame.intrinsics)
    )
    before = seg.segment(frame.rgb, "blue block")[0].area_px
    after = seg.segment(result.rgb, "blue block")[0].area_px
    assert after > 1.1 * before


def test_editor_refusals_are_provider_errors(sim_view):
    frame, _, _ = sim_view
    editor = OfflineEditor(OfflineSegmenter())
    for prompt, words in [
        ("close the red block", "'lid of the red block' matches no object"),
        ("put the purple block on the plate", "matches no object"),
        ("push the red block backward by 50 cm", "where it would end is outside the camera's view"),
        # 10 cm nearer the camera the cylinder would stand in the blue block
        ("push the green cylinder backward by 10 cm", "where it would end is too close to another object"),
    ]:
        with pytest.raises(ProviderError) as e:
            editor.edit(EditRequest(frame.rgb, prompt, frame.depth, frame.intrinsics))
        assert e.value.kind == "refused" and words in str(e.value), str(e.value)
    with pytest.raises(ProviderError, match="depth frame"):
        editor.edit(EditRequest(frame.rgb, "push the red block"))


def test_stand_up_turns_a_lying_bottle_upright(sim_profile_with, tmp_path):
    from drivers.sim import SimCamera, SimWorld

    (tmp_path / "bottle.yaml").write_text(
        "name: bottle\nobjects:\n"
        "  - {name: green_bottle, kind: bottle, radius_m: 0.03, height_m: 0.2, color: green, xy_m: [0.45, 0.0],"
        " lying: true, yaw_deg: 90}\n"
        "randomise: {xy_jitter_m: 0.0, yaw_jitter_deg: 0}\n"
    )
    profile = sim_profile_with({"sim": {"scene": "bottle", "scenes_dir": str(tmp_path)}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world) as camera:
        frame = camera.read()
    seg = OfflineSegmenter()
    result = OfflineEditor(seg).edit(EditRequest(frame.rgb, "stand the green bottle up", frame.depth, frame.intrinsics))
    R = result.T_goal_init_camera[:3, :3]
    up_camera = world.T_world_camera[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    assert abs(np.degrees(np.arccos(np.clip(np.trace(R) / 2 - 0.5, -1, 1))) - 90.0) < 1e-6
    assert abs(up_camera @ R @ up_camera) < 1e-6  # tipped about a horizontal axis
    R_base = world.T_world_camera[:3, :3] @ R @ world.T_world_camera[:3, :3].T
    neck = world.object_pose("green_bottle")[:3, :3] @ np.array([1.0, 0.0, 0.0])  # the lying bottle's neck side
    assert (R_base @ neck)[2] > 0.95  # stands on its base, neck up
    before, after = seg.segment(frame.rgb, "green bottle")[0], seg.segment(result.rgb, "green bottle")[0]
    (u0, v0, u1, v1), (a0, b0, a1, b1) = before.box, after.box
    assert (u1 - u0) > 2 * (v1 - v0)  # lying across the view
    assert (b1 - b0) > 1.5 * (a1 - a0)  # standing: taller than wide, its hidden side completed


@pytest.fixture(scope="module")
def task_view(sim_profile_with):
    """Captures of the paper's task scenes, by scene name: (frame, ground-truth masks, world)."""
    from drivers.sim import SimCamera, SimWorld

    views = {}

    def get(scene: str):
        if scene not in views:
            profile = sim_profile_with({"sim": {"scene": scene, "seed": 3}})
            world = SimWorld(profile.sim, profile.camera)
            with SimCamera(world) as camera:
                views[scene] = (camera.read(), camera.object_masks(), world)
        return views[scene]

    return get


@pytest.mark.parametrize(
    ("scene", "phrase", "name"),
    [
        ("tomato_pan", "the pan", "pan"),
        ("block_scale", "the black scale", "scale"),
        ("tomato_pan", "red ball", "tomato"),
    ],
)
def test_offline_segmenter_finds_dark_task_objects(task_view, scene, phrase, name):
    frame, masks, _ = task_view(scene)
    found = OfflineSegmenter().segment(frame.rgb, phrase)
    assert len(found) == 1, [d.label for d in found]
    iou = (found[0].mask & masks[name]).sum() / (found[0].mask | masks[name]).sum()
    assert iou > 0.85, f"{phrase}: IoU {iou:.2f}"


def test_editor_puts_the_ball_on_the_pan_floor(task_view):
    frame, _, world = task_view("tomato_pan")
    result = OfflineEditor(OfflineSegmenter()).edit(
        EditRequest(frame.rgb, "put the red ball in the pan", frame.depth, frame.intrinsics)
    )
    T_bc = world.T_world_camera
    T_motion_base = T_bc @ result.T_goal_init_camera @ np.linalg.inv(T_bc)
    ball, pan = world.object_pose("tomato")[:3, 3], world.object_pose("pan")[:3, 3]
    moved = T_motion_base[:3, :3] @ ball + T_motion_base[:3, 3]
    assert np.linalg.norm(moved[:2] - pan[:2]) < 0.02  # in the round body, not pulled towards the handle
    assert 0.004 < moved[2] - ball[2] < 0.016  # resting on the pan's 8 mm floor, not sunk into the table


def test_wide_end_tells_a_bottle_base_from_its_neck_and_not_a_plain_cylinder():
    from pipeline.reasoning.tabletop import Plane, footprint, wide_end

    plane = Plane(np.array([0.0, 0.0, 1.0]), 0.0)  # table z = 0, points above it
    rng = np.random.default_rng(0)
    s = rng.uniform(-0.09, 0.09, 4000)  # along x
    half_width = np.where(s > 0.036, 0.0135, 0.03)  # neck (30 % of the length) at +x
    pts = np.stack([s, rng.uniform(-1, 1, len(s)) * half_width, np.full(len(s), 0.05)], axis=1)
    axis = np.array([1.0, 0.0, 0.0])
    assert wide_end(footprint(pts, plane), plane, axis) == -1.0
    assert wide_end(footprint(pts * [-1, 1, 1], plane), plane, axis) == 1.0
    plain = pts.copy()
    plain[:, 1] = rng.uniform(-0.03, 0.03, len(s))
    assert wide_end(footprint(plain, plane), plane, axis) == 0.0
