"""Scene files load, compile into the world, and are placed deterministically without overlaps."""

import math
from pathlib import Path

import pytest

from drivers.sim.scene import SceneError, load_scene, place
from drivers.sim.world import SimWorld

SCENES = sorted((Path(__file__).resolve().parents[2] / "configs" / "scenes").glob("*.yaml"))


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_shipped_scene_compiles_and_settles_on_the_table(path, sim_profile_with):
    profile = sim_profile_with({"sim": {"scene": path.stem}})
    world = SimWorld(profile.sim, profile.camera)
    world.step(0.5)
    for o in world.scene.objects:
        T = world.object_pose(o.name)
        x, y, _ = world.poses[o.name]
        assert math.dist(T[:2, 3], (x, y)) < 0.02, f"{o.name} slid away from its placement"
        assert -0.01 < T[2, 3] < 0.3, f"{o.name} is not resting on the table"


def test_placement_is_seeded_and_overlap_free():
    scene = load_scene(SCENES[0].with_name("tabletop.yaml"))
    a, b, c = place(scene, 1), place(scene, 1), place(scene, 2)
    assert a == b and a != c
    names = [o.name for o in scene.objects]
    for i, n in enumerate(names):
        for m in names[i + 1 :]:
            assert math.dist(a[n][:2], a[m][:2]) > 0.02


def test_invalid_scene_is_rejected_with_file_and_reason(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "name: bad\nobjects:\n  - {name: cube, kind: box, color: mauve, size_m: [0.05, 0.05, 0.05], xy_m: [0.4, 0]}\n"
    )
    with pytest.raises(SceneError, match=r"bad\.yaml: object cube: unknown color 'mauve'"):
        load_scene(bad)
    bad.write_text("name: bad\nobjects:\n  - {name: ball, kind: sphere, xy_m: [0.4, 0]}\n")
    with pytest.raises(SceneError, match="ball of kind sphere needs radius_m"):
        load_scene(bad)
    bad.write_text(
        "name: bad\nobjects:\n  - {name: a, kind: sphere, radius_m: 0.2, xy_m: [0.4, 0]}\n"
        "  - {name: b, kind: sphere, radius_m: 0.2, xy_m: [0.45, 0]}\n"
    )
    with pytest.raises(SceneError, match=r"no placement with seed 0 keeps the footprints 20 mm apart.*a and b"):
        place(load_scene(bad), 0)
