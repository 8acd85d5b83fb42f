"""The task scenes: screws scattered by seed, objects standing on their supports, a brush resting on its bristles,
and all of it at rest before the first capture."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.sim.footprint import footprint_gap
from drivers.sim.scene import SceneError, expand_groups, load_scene, place, placed_footprint
from drivers.sim.world import SimWorld
from tests.conftest import CONFIGS


def test_screws_are_scattered_by_seed_apart_and_in_their_patch():
    scene = load_scene(CONFIGS / "scenes" / "table_sweep.yaml")
    group = scene.groups[0]
    counts = set()
    for seed in range(12):
        a, b = expand_groups(scene, seed), expand_groups(scene, seed)
        assert a == b
        members = [o for o in a.objects if o.group == "screw"]
        counts.add(len(members))
        assert group.count[0] <= len(members) <= group.count[1]
        outlines = [placed_footprint(o, (*o.xy_m, math.radians(o.yaw_deg))) for o in members]
        for i in range(len(members)):
            for j in range(i + 1, len(members)):
                assert footprint_gap(outlines[i], outlines[j]) >= group.min_gap_m - 1e-9
        centre = np.mean([o.xy_m for o in members], axis=0)
        assert np.linalg.norm(centre - group.centre_xy_m) < group.radius_m + scene.randomise.xy_jitter_m
        place(a, seed)  # the scene with its screws places without clashes
    assert len(counts) > 2  # the seed changes how many


def test_a_patch_too_small_for_its_group_is_a_scene_error(tmp_path):
    path = tmp_path / "crowded.yaml"
    path.write_text(
        "name: crowded\nobjects: []\ngroups:\n  - name: screw\n    item: {name: s, kind: screw, radius_m: 0.006, "
        "height_m: 0.045, xy_m: [0, 0]}\n    count: [30, 30]\n    centre_xy_m: [0.45, 0.0]\n    radius_m: 0.02\n"
    )
    with pytest.raises(SceneError, match="group screw: no room for 30 members in a patch of radius 20 mm"):
        expand_groups(load_scene(path), 0)


def test_an_object_must_stand_on_a_static_support(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(
        "name: bad\nobjects:\n  - {name: a, kind: box, size_m: [0.05, 0.05, 0.05], xy_m: [0.4, 0]}\n"
        "  - {name: b, kind: box, size_m: [0.03, 0.03, 0.03], xy_m: [0, 0], support: a}\n"
    )
    with pytest.raises(SceneError, match="object b stands on 'a': it must be a static object"):
        load_scene(path)


@pytest.mark.parametrize("seed", [7])
def test_task_scenes_rest_as_placed(sim_profile_with, seed):
    for name in ("table_sweep", "take_off", "pick_up"):
        world = SimWorld(sim_profile_with({"sim": {"scene": name, "seed": seed}}).sim, sim_profile_with().camera)
        before = {o.name: world.object_pose(o.name) for o in world.scene.objects}
        world.step(2.0)
        for o in world.scene.objects:
            T = world.object_pose(o.name)
            assert np.linalg.norm(T[:3, 3] - before[o.name][:3, 3]) < 0.002, f"{name}/{seed}: {o.name} moved"
            assert T[:3, 2] @ [0, 0, 1] > 0.99 or o.lying or o.kind == "screw", f"{o.name} tipped"
        if name == "take_off":  # on their supports' tops
            assert world.object_pose("red_block")[2, 3] == pytest.approx(0.09, abs=0.003)
            assert world.object_pose("plate")[2, 3] == pytest.approx(0.012, abs=0.003)
            assert np.linalg.norm(world.object_pose("red_block")[:2, 3] - world.object_pose("stand")[:2, 3]) < 0.01
