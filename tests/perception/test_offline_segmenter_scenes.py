"""The offline segmenter on rendered scenes, checked against the simulator's own segmentation: shape words alone
in the task scenes, lids of every colour open and shut, and every phrase of generated scenes it was not tuned on."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from drivers.sim.generate import generate_case, phrases
from drivers.types import RGBDFrame
from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.perception.segmenter import matches
from sim_helpers import set_hinge, write_scene


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def view(sim_profile_with, scene: str, seed: int = 0):
    from drivers.sim import SimCamera, SimWorld

    profile = sim_profile_with({"sim": {"scene": scene, "seed": seed}})
    world = SimWorld(profile.sim, profile.camera)
    camera = SimCamera(world, seed=0)
    camera.connect()
    return world, camera


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_scale_alone_is_the_scale_and_the_blocks_are_counted_by_what_they_are(sim_profile_with, seed):
    _, camera = view(sim_profile_with, "block_scale", seed)
    with camera:
        rgb, truth = camera.read().rgb, camera.object_masks()
    seg = OfflineSegmenter()
    (scale,) = seg.segment(rgb, "the scale")
    assert iou(scale.mask, truth["scale"]) > 0.8
    blocks = seg.segment(rgb, "the block")
    assert sorted(max(truth, key=lambda n: (truth[n] & d.mask).sum()) for d in blocks) == ["blue_block", "yellow_block"]
    assert matches(blocks).startswith("matches 2 objects: a ") and "box at (" in matches(blocks)


@pytest.mark.parametrize(
    ("lid_color", "yaw_deg"), [(None, 0.0), ("blue", 25.0), ("yellow", -30.0), ("dark_blue", 40.0)]
)
def test_a_lid_is_found_open_and_shut_whatever_its_colour(sim_profile_with, tmp_path, lid_color, yaw_deg):
    """A lid of another colour, of the box's own colour, or a darker shade of it (the default)."""
    box = {"name": "box", "kind": "lidded_box", "size_m": [0.12, 0.15, 0.07], "color": "blue", "xy_m": [0.5, 0.05]}
    box |= {"yaw_deg": yaw_deg, "lid_open_deg": 95.0} | ({"lid_color": lid_color} if lid_color else {})
    path = tmp_path / "lid.yaml"
    path.write_text(yaml.safe_dump({"name": "lid", "objects": [box], "randomise": {"xy_jitter_m": 0.0}}))
    world, camera = view(sim_profile_with, str(path))
    seg = OfflineSegmenter()
    with camera:
        for shut in (False, True):
            if shut:
                set_hinge(world, "box_hinge", math.radians(0.5))
            frame = camera.read()
            for depth in (None, frame.depth):  # the lid meets its box in depth too
                lids = seg.segment(frame.rgb, "the lid of the blue box", depth)
                assert len(lids) == 1, (shut, [d.label for d in lids])
                assert iou(lids[0].mask, camera.body_mask("box_lid")) > 0.6, f"shut={shut}"


def test_the_lid_of_a_box_is_the_open_chests_beside_a_plain_box_of_its_colour(sim_profile_with, tmp_path):
    """'the box' names both a chest and a block of its colour; the lid is the chest's, seen open."""
    chest = {"name": "box", "kind": "lidded_box", "size_m": [0.12, 0.15, 0.07], "color": "pink", "xy_m": [0.5, 0.1]}
    chest |= {"lid_open_deg": 95.0}
    block = {"name": "block", "kind": "box", "size_m": [0.05, 0.05, 0.05], "color": "pink", "xy_m": [0.45, -0.15]}
    path = tmp_path / "lid.yaml"
    scene = {"name": "lid", "objects": [chest, block], "randomise": {"xy_jitter_m": 0.0}}
    path.write_text(yaml.safe_dump(scene))
    _, camera = view(sim_profile_with, str(path))
    with camera:
        rgb = camera.read().rgb
        assert len(OfflineSegmenter().segment(rgb, "the pink box")) == 2
        lids = OfflineSegmenter().segment(rgb, "the lid of the pink box")
        assert len(lids) == 1, [d.label for d in lids]
        assert iou(lids[0].mask, camera.body_mask("box_lid")) > 0.6


def test_the_lid_of_a_shut_chest_is_the_largest_box_of_its_colours(sim_profile_with, tmp_path):
    """Shut, a chest looks like a box; a block of a paler shade of its colour beside it has no lid of the chest's
    (after a close, verification found the lid twice)."""
    chest = {
        "name": "box",
        "kind": "lidded_box",
        "size_m": [0.123, 0.132, 0.059],
        "color": "cyan",
        "xy_m": [0.45, 0.12],
    }
    chest |= {"yaw_deg": 15.0, "lid_open_deg": 0.0}
    block = {"name": "block", "kind": "box", "size_m": [0.057, 0.047, 0.057], "color": "light_cyan"}
    block |= {"xy_m": [0.5, -0.1], "yaw_deg": -119.0}
    path = tmp_path / "shut.yaml"
    path.write_text(yaml.safe_dump({"name": "shut", "objects": [chest, block], "randomise": {"xy_jitter_m": 0.0}}))
    _, camera = view(sim_profile_with, str(path))
    with camera:
        rgb = camera.read().rgb
        lids = OfflineSegmenter().segment(rgb, "the lid of the cyan chest")
        assert len(lids) == 1, [d.label for d in lids]
        assert iou(lids[0].mask, camera.body_mask("box_lid")) > 0.6


@pytest.mark.parametrize(
    ("yaw_deg", "xy_m", "radius_m"),
    [
        pytest.param(
            -157.0,
            [0.29, 0.15],
            0.07,
            marks=pytest.mark.xfail(
                strict=True,
                reason="known limit: this pan is half hidden behind the chest's open lid, and what is seen of its "
                "body (a bar-like part beside a narrow handle) reads as a brush",
            ),
        ),
        (158.0, [0.35, -0.05], 0.099),
        (180.0, [0.3, -0.15], 0.08),
    ],
)
def test_a_pan_whose_handle_points_away_from_the_camera_is_a_pan(sim_profile_with, tmp_path, yaw_deg, xy_m, radius_m):
    """Seen end-on the handle is short: the pan is told by its round body once the handle is cut off, and an open
    chest beside it stays a chest."""
    pan = {"name": "pan", "kind": "pan", "radius_m": radius_m, "height_m": 0.035, "color": "red", "xy_m": xy_m}
    chest = {"name": "box", "kind": "lidded_box", "size_m": [0.12, 0.15, 0.07], "color": "blue", "xy_m": [0.5, 0.2]}
    scene = {"objects": [pan | {"yaw_deg": yaw_deg}, chest | {"lid_open_deg": 95.0}], "randomise": {"xy_jitter_m": 0}}
    path = tmp_path / "pan.yaml"
    path.write_text(yaml.safe_dump({"name": "pan"} | scene))
    _, camera = view(sim_profile_with, str(path))
    seg = OfflineSegmenter()
    with camera:
        rgb, truth = camera.read().rgb, camera.object_masks()
    pans = seg.segment(rgb, "the pan")
    assert len(pans) == 1, matches(pans)
    assert iou(pans[0].mask, truth["pan"]) > 0.6
    chests = seg.segment(rgb, "the chest")
    assert len(chests) == 1 and iou(chests[0].mask, truth["box"]) > 0.6, matches(chests)


def test_phrases_of_generated_scenes_find_exactly_their_object(sim_profile_with):
    """Held-out seeds (the segmenter's cues were set on seeds 0-99): at least 90 % of all phrases that name one
    object in a scene (colour and noun, shade words, the noun alone) find exactly that object."""
    seg = OfflineSegmenter()
    right = total = 0
    wrong = []
    for seed in range(3000, 3016):
        case = generate_case(seed)
        _, camera = view(sim_profile_with, case.scene_name)
        with camera:
            rgb, truth = camera.read().rgb, camera.object_masks()
        for o in case.scene.objects:
            if truth[o.name].sum() < 60:  # hidden behind another object
                continue
            for phrase in phrases(case.scene, o.name):
                found = seg.segment(rgb, phrase)
                ok = len(found) == 1 and max(truth, key=lambda n: (truth[n] & found[0].mask).sum()) == o.name
                right += ok
                total += 1
                if not ok:
                    wrong.append(f"{seed} {phrase!r}: {matches(found)}")
    assert right >= 0.9 * total, f"{right}/{total}:\n" + "\n".join(wrong)


def test_a_scale_is_told_by_its_plate_in_a_shadow_or_on_a_gray_base_and_white_boxes_are_no_scales(
    sim_profile_with, tmp_path
):
    """A purple scale in the arm's shadow (its light plate reads gray there) and a gray scale (plate and base are
    one neutral region of two shades, named by its base: a gray ball beside it is no scale) are scales; a white
    block and a white chest, open and shut, whose shaded faces are a lighter shade of the same white, are not."""
    objects = [
        {"name": "purple_scale", "kind": "platform", "size_m": [0.106, 0.093, 0.021], "color": "purple"},
        {"name": "gray_scale", "kind": "platform", "size_m": [0.12, 0.09, 0.03], "color": "gray"},
        {"name": "block", "kind": "box", "size_m": [0.05, 0.05, 0.05], "color": "white"},
        {"name": "chest", "kind": "lidded_box", "size_m": [0.12, 0.15, 0.06], "color": "white", "lid_open_deg": 95.0},
        {"name": "ball", "kind": "sphere", "radius_m": 0.025, "color": "gray"},
    ]
    places = [([0.33, -0.06], 97.0), ([0.6, -0.1], 30.0), ([0.45, -0.3], 10.0), ([0.5, 0.2], 0.0), ([0.38, 0.08], 0.0)]
    for o, (xy, yaw) in zip(objects, places, strict=True):
        o |= {"xy_m": xy, "yaw_deg": yaw}
    path = tmp_path / "scales.yaml"
    path.write_text(yaml.safe_dump({"name": "scales", "objects": objects, "randomise": {"xy_jitter_m": 0.0}}))
    world, camera = view(sim_profile_with, str(path))
    seg = OfflineSegmenter()
    with camera:
        for shut in (False, True):
            if shut:
                set_hinge(world, "chest_hinge", math.radians(0.5))
            rgb, truth = camera.read().rgb, camera.object_masks()
            scales = seg.segment(rgb, "the scale")
            assert sorted(_named(scales, truth)) == ["gray_scale", "purple_scale"], (shut, matches(scales))
            for phrase, name in (("the gray scale", "gray_scale"), ("the purple scale", "purple_scale")):
                (scale,) = seg.segment(rgb, phrase)
                assert iou(scale.mask, truth[name]) > 0.8, phrase
            # open, the chest is a chest; shut, it looks like a box (so "box" names both): neither is a scale
            boxes = _named(seg.segment(rgb, "the white box"), truth)
            assert sorted(boxes) == ["block", "chest"], (shut, list(boxes))
            assert all(iou(d.mask, truth[n]) > 0.8 for n, d in boxes.items()), shut


def _named(detections: list, truth: dict[str, np.ndarray]) -> dict:
    """Each detection by the name of the object it covers most."""
    return {max(truth, key=lambda n: (truth[n] & d.mask).sum()): d for d in detections}


def _placed_view(sim_profile_with, tmp_path, name: str, objects: list[dict], places) -> tuple[RGBDFrame, dict]:
    """The capture of a scene of these objects set at (x, y, yaw) exactly, and each object's true mask."""
    for o, (x, y, yaw) in zip(objects, places, strict=True):
        o |= {"xy_m": [x, y], "yaw_deg": yaw}
    path = write_scene(tmp_path / f"{name}.yaml", objects)
    _, camera = view(sim_profile_with, str(path))
    with camera:
        return camera.read(), camera.object_masks()


def _placed_instances(
    sim_profile_with, tmp_path, name: str, objects: list[dict], places, with_depth: bool = False
) -> list[tuple[str, str, float]]:
    """The segmenter's instances in a scene of these objects set at (x, y, yaw) exactly (given its depth image, or
    not): for each, the object it covers most, its kind and its overlap with that object."""
    frame, truth = _placed_view(sim_profile_with, tmp_path, name, objects, places)
    out = []
    for i in OfflineSegmenter().instances(frame.rgb, frame.depth if with_depth else None):
        covered = max(truth, key=lambda n: (truth[n] & i.region.mask).sum())
        out.append((covered, i.kind, iou(i.region.mask, truth[covered])))
    return out


def _kinds_of_the_objects(instances: list[tuple[str, str, float]]) -> dict[str, str]:
    """The kind of each object an instance covers well (overlap above 0.8)."""
    return {covered: kind for covered, kind, overlap in instances if overlap > 0.8}


def test_small_blocks_balls_and_standing_cans_are_told_by_their_shading(sim_profile_with, tmp_path):
    """At 15-30 px across a block, a ball and a standing can have outlines too alike to be told by (a small block
    read as a ball, a can as a block); their shading tells them: a block is level faces, a ball has none, a can
    has a level top above a side shaded across. Cans in the light and in the arm's shadow, blocks at two yaws; a
    pale can lying in the light, its side clipped, is told by its outline."""
    objects = [
        {"name": "pale_block", "kind": "box", "size_m": [0.033, 0.031, 0.042], "color": "light_pink"},
        {"name": "block", "kind": "box", "size_m": [0.048, 0.042, 0.057], "color": "purple", "yaw_deg": 41.0},
        {"name": "ball", "kind": "sphere", "radius_m": 0.027, "color": "purple"},
        {"name": "shaded_can", "kind": "cylinder", "radius_m": 0.024, "height_m": 0.057, "color": "green"},
        {"name": "wide_can", "kind": "cylinder", "radius_m": 0.037, "height_m": 0.069, "color": "green"},
        {"name": "can", "kind": "cylinder", "radius_m": 0.023, "height_m": 0.066, "color": "dark_pink"},
        {"name": "pale_can", "kind": "cylinder", "radius_m": 0.023, "height_m": 0.099, "color": "light_yellow"},
    ]
    places = ([0.6, -0.05, -50.0], [0.42, -0.14, 41.0], [0.45, -0.3, 0.0], [0.355, -0.09, 0.0], [0.25, 0.22, 0.0])
    places += ([0.55, 0.12, 0.0], [0.415, 0.255, 140.0])
    objects[-1]["lying"] = True  # in the light its side clips but for a sliver: too little shading to read
    instances = _placed_instances(sim_profile_with, tmp_path, "small", objects, places)
    for covered, _, overlap in instances:
        assert overlap > 0.8, covered
    assert _kinds_of_the_objects(instances) == {o["name"]: o["kind"] for o in objects}


def test_a_bottle_lying_behind_an_open_chest_is_a_bottle_not_the_chests_lid(sim_profile_with, tmp_path):
    """In the image the bottle touches the top of the chest's open lid and peeks out beside it: it rests on the
    chest along part of its width only, where a lid rests on its box along all of it."""
    chest = {"name": "chest", "kind": "lidded_box", "size_m": [0.123, 0.123, 0.063], "color": "dark_cyan"}
    chest |= {"xy_m": [0.579, -0.07], "yaw_deg": -5.6, "lid_open_deg": 93.0}
    bottle = {"name": "bottle", "kind": "bottle", "radius_m": 0.031, "height_m": 0.217, "color": "dark_yellow"}
    bottle |= {"xy_m": [0.332, -0.014], "yaw_deg": -89.5, "lying": True}
    path = write_scene(tmp_path / "behind.yaml", [chest, bottle])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        rgb, truth = camera.read().rgb, camera.object_masks()
        lid_truth = camera.body_mask("chest_lid")
    seg = OfflineSegmenter()
    (found,) = seg.segment(rgb, "the yellow bottle")
    assert iou(found.mask, truth["bottle"]) > 0.8
    (lid,) = seg.segment(rgb, "the lid of the cyan box")
    assert iou(lid.mask, lid_truth) > 0.6


def test_a_block_half_hidden_behind_a_chest_of_its_colour_is_the_block_not_the_chest(sim_profile_with, tmp_path):
    """What is seen of the block reads as a speck (no kind a block's shape fits); of the regions of its colour the
    chest, surely a chest, is no block: the block is what is left (held-out seed 9026 matched both)."""
    chest = {"name": "chest", "kind": "lidded_box", "size_m": [0.126, 0.135, 0.078], "color": "light_pink"}
    chest |= {"xy_m": [0.57, 0.095], "yaw_deg": -29.5, "lid_open_deg": 94.0, "lid_color": "dark_red"}
    block = {"name": "block", "kind": "box", "size_m": [0.047, 0.062, 0.056], "color": "pink"}
    block |= {"xy_m": [0.369, 0.095], "yaw_deg": -33.0}
    path = write_scene(tmp_path / "hidden.yaml", [chest, block])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        rgb, truth = camera.read().rgb, camera.object_masks()
    (found,) = OfflineSegmenter().segment(rgb, "the pink block")
    assert iou(found.mask, truth["block"]) > 0.7


@pytest.mark.parametrize(
    "behind",
    [
        {"kind": "bottle", "color": "blue", "radius_m": 0.033, "height_m": 0.167, "xy_m": [0.349, -0.26]},
        {"kind": "bowl", "color": "light_cyan", "radius_m": 0.065, "height_m": 0.053, "xy_m": [0.36, -0.22]},
    ],
)
def test_a_thing_standing_behind_an_open_chest_is_no_lid_where_depth_shows_it_farther(
    sim_profile_with, tmp_path, behind
):
    """In the image a bottle or a bowl behind the chest rests on its top along its width, as a lid of another colour
    would; the depth where the two regions meet shows it 15 cm and more behind the chest, where a lid on its hinge
    meets its box within millimetres. With the depth, the lid is the chest's own and the thing is found as itself."""
    chest = {"name": "chest", "kind": "lidded_box", "size_m": [0.108, 0.132, 0.072], "color": "gray"}
    chest |= {"xy_m": [0.57, -0.16], "yaw_deg": 19.6, "lid_open_deg": 100.8, "lid_color": "gray"}
    path = write_scene(tmp_path / "behind.yaml", [chest, {"name": "thing", **behind}])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        frame, truth = camera.read(), camera.object_masks()
        lid_truth = camera.body_mask("chest_lid")
    seg = OfflineSegmenter()
    thing = f"the {behind['color'].split('_')[-1]} {behind['kind']}"
    blind = seg.segment(frame.rgb, "the lid of the gray box")  # the image alone takes the thing for the lid
    assert len(blind) == 1 and iou(blind[0].mask, truth["thing"]) > 0.5
    (lid,) = seg.segment(frame.rgb, "the lid of the gray box", frame.depth)
    assert iou(lid.mask, lid_truth) > 0.4 and (lid.mask & truth["thing"]).sum() == 0
    (found,) = seg.segment(frame.rgb, thing, frame.depth)
    assert iou(found.mask, truth["thing"]) > 0.8


def test_an_open_chest_that_reads_as_a_dustpan_as_well_has_its_lid_found(sim_profile_with, tmp_path):
    """Turned so its open lid stands over its side, the chest fits a dustpan a little better than a chest (a scoop
    with a raised back) and a chest confidently: the lid of the box is still its lid."""
    chest = {"name": "chest", "kind": "lidded_box", "size_m": [0.123, 0.165, 0.066], "color": "dark_red"}
    chest |= {"xy_m": [0.4705, -0.2461], "yaw_deg": -42.35, "lid_open_deg": 81.9}
    path = write_scene(tmp_path / "dustpan_like.yaml", [chest])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        frame = camera.read()
        lid_truth = camera.body_mask("chest_lid")
    seg = OfflineSegmenter()
    (region,) = seg.instances(frame.rgb)
    assert region.kind != "lidded_box" and region.scores["lidded_box"] >= 0.8  # the premise: it reads as both
    (lid,) = seg.segment(frame.rgb, "the lid of the dark red box", frame.depth)
    assert iou(lid.mask, lid_truth) > 0.5


def test_a_pan_whose_washed_out_handle_reads_apart_is_the_pan_a_bowl_alone_would_be(sim_profile_with, tmp_path):
    """A light pink pan's lit handle reads white, a region of its own, and the body alone is a shallow bowl: "the
    pan", with no region of a pan's kind nor fitting one, is the one region of the kind it looks like."""
    pan = {"name": "pan", "kind": "pan", "color": "light_pink", "radius_m": 0.095, "height_m": 0.038}
    pan |= {"xy_m": [0.5294, 0.3054], "yaw_deg": 159.82}
    ball = {"name": "ball", "kind": "sphere", "color": "light_green", "radius_m": 0.039, "xy_m": [0.315, 0.2364]}
    path = write_scene(tmp_path / "pan.yaml", [pan, ball])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        frame, truth = camera.read(), camera.object_masks()
    seg = OfflineSegmenter()
    assert "pan" not in {i.kind for i in seg.instances(frame.rgb)}  # the premise: no region reads as a pan
    (found,) = seg.segment(frame.rgb, "the pan", frame.depth)
    assert iou(found.mask, truth["pan"]) > 0.7
    # a kind with no look-alike by shape alone: still nothing (the white handle reads as a can, and is no bottle)
    assert seg.segment(frame.rgb, "the bottle", frame.depth) == []


def test_a_bottles_body_apart_from_its_neck_reads_as_a_can_and_is_still_the_bottle(sim_profile_with, tmp_path):
    """An edited goal may draw a lying bottle with a seam below its neck: the body alone is surely a can, the neck a
    fragment. "the cyan bottle", with no region of its kind, keeps the can-like body beside the fragment (generated
    case 5042, where only the neck was kept and grounding failed); "the cyan can" still names the can alone."""
    can = {"name": "body", "kind": "cylinder", "lying": True, "color": "cyan", "radius_m": 0.03, "height_m": 0.12}
    can |= {"xy_m": [0.45, 0.05], "yaw_deg": 30.0}
    neck = {"name": "neck", "kind": "box", "color": "cyan", "size_m": [0.02, 0.018, 0.016], "xy_m": [0.55, -0.12]}
    path = write_scene(tmp_path / "bottle_apart.yaml", [can, neck])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        frame, truth = camera.read(), camera.object_masks()
    seg = OfflineSegmenter()
    body = next(i for i in seg.instances(frame.rgb) if iou(i.region.mask, truth["body"]) > 0.8)
    assert body.kind == "cylinder" and body.scores["cylinder"] >= 0.8  # the premise: surely a can
    found = seg.segment(frame.rgb, "the cyan bottle", frame.depth)
    assert [max(truth, key=lambda n: (truth[n] & d.mask).sum()) for d in found] == ["body", "neck"]
    (only,) = seg.segment(frame.rgb, "the cyan can", frame.depth)
    assert iou(only.mask, truth["body"]) > 0.8


def test_light_cans_lying_in_the_light_are_cans_though_their_sides_clip(sim_profile_with, tmp_path):
    """A light can lying in the light clips along most of its side; the band left ramps across it (a curved
    surface), which a box's faces never do, so it is no block; blocks beside them stay blocks (generated scenes
    10338, 10443, 10362, 10448, 10108, 10331, where these cans read as blocks)."""
    can = {"kind": "cylinder", "lying": True}
    objects = [
        can | {"name": "orange_can", "color": "orange", "radius_m": 0.025, "height_m": 0.117},
        can | {"name": "cyan_can", "color": "cyan", "radius_m": 0.027, "height_m": 0.118},
        can | {"name": "white_can", "color": "white", "radius_m": 0.026, "height_m": 0.094},
        can | {"name": "light_red_can", "color": "light_red", "radius_m": 0.029, "height_m": 0.108},
        {"name": "purple_block", "kind": "box", "color": "purple", "size_m": [0.042, 0.048, 0.037]},
        {"name": "pink_block", "kind": "box", "color": "pink", "size_m": [0.064, 0.036, 0.048]},
    ]
    places = ([0.525, -0.042, 77.5], [0.49, 0.19, -113.9], [0.353, -0.242, 85.9], [0.427, 0.044, -51.6])
    places += ([0.332, 0.147, -81.8], [0.26, 0.199, 157.1])
    instances = _placed_instances(sim_profile_with, tmp_path, "cans", objects, places)
    assert _kinds_of_the_objects(instances) == {o["name"]: o["kind"] for o in objects}


def test_dark_cans_lying_in_the_arms_shadow_are_cans_not_open_chests(sim_profile_with, tmp_path):
    """A dark can's highlight band makes edges inside it, as an open chest's walls do, but its side ramps all over,
    where a chest's walls and floor are level (generated scenes 10298 and 10536, where these read as chests)."""
    can = {"kind": "cylinder", "lying": True}
    objects = [
        can | {"name": "dark_green_can", "color": "dark_green", "radius_m": 0.024, "height_m": 0.106},
        can | {"name": "dark_yellow_can", "color": "dark_yellow", "radius_m": 0.027, "height_m": 0.111},
    ]
    places = ([0.3165, 0.1425, -89.9], [0.3524, 0.2914, -104.3])
    instances = _placed_instances(sim_profile_with, tmp_path, "dark_cans", objects, places)
    assert _kinds_of_the_objects(instances) == {"dark_green_can": "cylinder", "dark_yellow_can": "cylinder"}


def test_white_scales_in_the_light_are_scales_beside_a_white_open_chest_and_block(sim_profile_with, tmp_path):
    """A white scale's plate and base both clip white: no plate of another shade tells it. Its plate's rim makes as
    many edges inside it as an open chest's walls do, but its core stays lit where a chest's inner walls and floor
    are in shade (generated scenes 8078, 10137, 10294, where these scales read as open chests)."""
    scale = {"kind": "platform", "color": "white"}
    objects = [
        scale | {"name": "scale_a", "size_m": [0.103, 0.096, 0.036]},
        scale | {"name": "scale_b", "size_m": [0.098, 0.108, 0.032]},
        scale | {"name": "scale_c", "size_m": [0.114, 0.108, 0.021]},
        {"name": "chest", "kind": "lidded_box", "color": "white", "size_m": [0.12, 0.15, 0.06], "lid_open_deg": 95.0},
        {"name": "block", "kind": "box", "color": "white", "size_m": [0.05, 0.05, 0.05]},
    ]
    places = ([0.41, 0.268, -13.2], [0.558, -0.045, 112.4], [0.513, -0.286, 143.3], [0.35, -0.3, 0.0])
    places += ([0.34, -0.12, 20.0],)
    instances = _placed_instances(sim_profile_with, tmp_path, "white_scales", objects, places)
    assert _kinds_of_the_objects(instances) == {o["name"]: o["kind"] for o in objects}
    # named by their own colour (not, as a light plate on a gray base is, by a base's), and no box
    _, camera = view(sim_profile_with, str(tmp_path / "white_scales.yaml"))
    with camera:
        rgb, truth = camera.read().rgb, camera.object_masks()
    seg = OfflineSegmenter()
    assert sorted(_named(seg.segment(rgb, "the white scale"), truth)) == ["scale_a", "scale_b", "scale_c"]
    assert sorted(_named(seg.segment(rgb, "the white box"), truth)) == ["block", "chest"]


def test_a_pale_bottles_cap_in_the_light_is_the_bottles_not_the_pan_behind_it(sim_profile_with, tmp_path):
    """A light pink bottle standing in front of a cyan pan: its cap's top clips to near white, faintly pink, and
    borders the pan more than the bottle. It is the bottle's face, not the pan's (generated case 5079, where the
    pan's region reached onto the cap and the pan's rim was placed 20 cm off)."""
    objects = [
        {"name": "pan", "kind": "pan", "color": "cyan", "radius_m": 0.081, "height_m": 0.034},
        {"name": "bottle", "kind": "bottle", "color": "light_pink", "radius_m": 0.034, "height_m": 0.173},
    ]
    places = ([0.4086, 0.0175, -160.4], [0.6084, -0.0237, 131.4])
    frame, truth = _placed_view(sim_profile_with, tmp_path, "cap", objects, places)
    rgb = frame.rgb
    found = {max(truth, key=lambda n: (truth[n] & i.region.mask).sum()): i for i in OfflineSegmenter().instances(rgb)}
    assert found["pan"].kind == "pan" and found["bottle"].kind == "bottle"
    assert (found["pan"].region.mask & truth["bottle"]).sum() < 20
    assert iou(found["bottle"].region.mask, truth["bottle"]) > 0.9


@pytest.mark.parametrize(
    ("radius_m", "height_m", "place"), [(0.085, 0.036, [0.337, 0.014, -145.8]), (0.092, 0.046, [0.29, 0.108, 44.8])]
)
def test_a_black_pan_that_meets_the_arm_in_the_image_is_found(sim_profile_with, tmp_path, radius_m, height_m, place):
    """A black pan below the gripper: in the image its rim or handle touches the arm, and the unsaturated region
    of arm, floor and pan reaches the image border (generated cases 5007 and 10125, where "the pan" matched no
    object). The black part of such a region is an object of its own."""
    pan = {"name": "pan", "kind": "pan", "color": "black", "radius_m": radius_m, "height_m": height_m}
    frame, truth = _placed_view(sim_profile_with, tmp_path, "black_pan", [pan], [place])
    rgb = frame.rgb
    found = [i for i in OfflineSegmenter().instances(rgb) if iou(i.region.mask, truth["pan"]) > 0.9]
    assert [(i.kind, i.region.colour) for i in found] == [("pan", "black")]


def test_a_scale_whose_base_is_partly_hidden_is_a_scale(sim_profile_with, tmp_path):
    """A can in front of a light pink scale hides the middle of the base's sides, which then read as two pieces,
    neither spanning the white plate's width: the pieces together are the base (generated case 5002, where the
    plate read as a white box and "the cube" matched it; 10158 alike)."""
    objects = [
        {"name": "scale", "kind": "platform", "color": "light_pink", "size_m": [0.092, 0.102, 0.032]},
        {"name": "can", "kind": "cylinder", "color": "light_blue", "radius_m": 0.024, "height_m": 0.102},
    ]
    places = ([0.367, 0.047, 4.8], [0.508, 0.049, 0.0])
    instances = _placed_instances(sim_profile_with, tmp_path, "hidden_base", objects, places)
    assert _kinds_of_the_objects(instances) == {"scale": "platform", "can": "cylinder"}


def test_a_pale_lying_bottle_is_no_platform_and_a_small_ball_no_plate(sim_profile_with, tmp_path):
    """A light pink bottle lying in the light: its lit faces are near neutral, a light plate on top as a scale's is,
    but a platform is about as deep as it is wide (generated case 11088: 'the platform' matched it and the real
    one). A small ball seen a little wider than tall has a plate's outline, but its shading has no level face
    (11021: 'the ball' matched nothing)."""
    objects = [
        {"name": "bottle", "kind": "bottle", "color": "light_pink", "radius_m": 0.028, "height_m": 0.197},
        {"name": "ball", "kind": "sphere", "color": "purple", "radius_m": 0.026},
        {"name": "platform", "kind": "platform", "color": "light_red", "size_m": [0.1, 0.117, 0.036]},
        {"name": "bowl", "kind": "bowl", "color": "dark_cyan", "radius_m": 0.086, "height_m": 0.051},
    ]
    objects[0]["lying"] = True
    places = ([0.3158, 0.094, -115.55], [0.3905, -0.1032, 99.41], [0.418, -0.24, -2.8], [0.55, 0.25, -39.6])
    instances = _placed_instances(sim_profile_with, tmp_path, "pale", objects, places)
    assert _kinds_of_the_objects(instances) == {o["name"]: o["kind"] for o in objects}


def test_depth_tells_a_dark_bowl_from_a_plate_and_an_open_chest_from_a_block(sim_profile_with, tmp_path):
    """A dark bowl seen from above is a dark ring and a dark inside with no edges between them: by its outline a
    plate (generated case 12067: 'the plate' matched it and the plate); an open chest's body, its lid of another
    colour, a block (13078: 'the cube' matched two chests). The depth image tells: a container's inside lies
    behind its rim, a plate is flat, a block's middle stands before its outline."""
    objects = [
        {"name": "bowl", "kind": "bowl", "color": "dark_blue", "radius_m": 0.089, "height_m": 0.08},
        {"name": "plate", "kind": "plate", "color": "light_yellow", "radius_m": 0.084, "height_m": 0.013},
        {"name": "cube", "kind": "box", "color": "dark_cyan", "size_m": [0.039, 0.044, 0.037]},
        {"name": "chest", "kind": "lidded_box", "color": "green", "size_m": [0.1, 0.13, 0.071], "lid_open_deg": 89.6},
    ]
    objects[-1]["lid_color"] = "yellow"
    places = ([0.2855, -0.1443, -28.18], [0.62, -0.05, -99.13], [0.4533, -0.1919, -61.47], [0.4964, 0.1927, 33.7])
    instances = _placed_instances(sim_profile_with, tmp_path, "relief", objects, places, with_depth=True)
    assert _kinds_of_the_objects(instances) == {"bowl": "bowl", "plate": "plate", "cube": "box"}
    assert "lidded_box" in {kind for covered, kind, _ in instances if covered == "chest"}  # (its lid: a region apart)
    frame, _ = _placed_view(sim_profile_with, tmp_path, "relief", objects, places)
    seg = OfflineSegmenter()
    for phrase in ("the plate", "the bowl", "the cube", "the chest"):
        assert len(seg.segment(frame.rgb, phrase, frame.depth)) == 1, phrase


LYING = {"lying": True}
BLOCK_AND_BLACK_CAN = (
    [
        {"name": "block", "kind": "box", "color": "blue", "size_m": [0.03, 0.06, 0.06]},
        {"name": "can", "kind": "cylinder", "color": "black", "radius_m": 0.027, "height_m": 0.108},
        {"name": "dish", "kind": "plate", "color": "cyan", "radius_m": 0.079, "height_m": 0.015},
        {"name": "plate", "kind": "plate", "color": "dark_pink", "radius_m": 0.081, "height_m": 0.018},
        {"name": "bottle", "kind": "bottle", "color": "light_yellow", "radius_m": 0.025, "height_m": 0.166} | LYING,
    ],
    (
        [0.3745, 0.0001, 115.97],
        [0.4298, 0.2523, -0.14],
        [0.4465, -0.1531, -16.45],
        [0.2332, -0.2033, 129.0],
        [0.2612, 0.1764, 32.91],
    ),
    ("the box", "block"),
)
BALL_AND_PLATE = (
    [
        {"name": "ball", "kind": "sphere", "color": "orange", "radius_m": 0.034},
        {"name": "plate", "kind": "plate", "color": "light_red", "radius_m": 0.081, "height_m": 0.017},
    ],
    ([0.3934, 0.0475, 83.13], [0.3702, 0.2882, -167.5]),
    ("the sphere", "ball"),
)


@pytest.mark.parametrize(("objects", "places", "named"), [BLOCK_AND_BLACK_CAN, BALL_AND_PLATE], ids=["tie", "ball"])
def test_a_shape_word_keeps_the_region_that_reads_only_as_its_kind_and_a_ball_is_told_by_its_relief(
    sim_profile_with, tmp_path, objects, places, named
):
    """A black can's shading is unreadable: it fits a block as well as a can, and 'the box' matched it and the
    blue block (generated case 12096); the one that reads as a block alone is the block. An orange ball shows edges
    inside (its shadow's line), which without depth say rim or inner walls: with depth, no inside lies behind its
    outline, and 'the sphere' finds it (14071)."""
    frame, truth = _placed_view(sim_profile_with, tmp_path, "ties", [dict(o) for o in objects], places)
    phrase, name = named
    found = OfflineSegmenter().segment(frame.rgb, phrase, frame.depth)
    assert len(found) == 1, [d.label for d in found]
    assert iou(found[0].mask, truth[name]) > 0.7


def test_a_lid_shares_no_pixels_with_a_chest_of_its_colour_behind_its_box(sim_profile_with, tmp_path):
    """A blue lid open on a green chest and a light blue chest behind it are one region in the image: the lid is
    cut off it where the depth steps (the goal moved both, and the contact plan turned 170 deg)."""
    front = {"name": "front", "kind": "lidded_box", "color": "green", "size_m": [0.124, 0.146, 0.056]}
    front |= {"xy_m": [0.5509, -0.2604], "yaw_deg": -7.13, "lid_open_deg": 89.9, "lid_color": "blue"}
    back = {"name": "back", "kind": "lidded_box", "color": "light_blue", "size_m": [0.121, 0.144, 0.064]}
    back |= {"xy_m": [0.2758, -0.2141], "yaw_deg": -43.15, "lid_open_deg": 98.2, "lid_color": "light_purple"}
    path = write_scene(tmp_path / "behind.yaml", [front, back])
    _, camera = view(sim_profile_with, str(path))
    with camera:
        frame, truth = camera.read(), camera.object_masks()
        lid = camera.body_mask("front_lid")
    (found,) = OfflineSegmenter().segment(frame.rgb, "the lid of the green box", frame.depth)
    assert (found.mask & truth["back"]).sum() < 0.02 * found.area_px
    assert iou(found.mask, lid) > 0.6
