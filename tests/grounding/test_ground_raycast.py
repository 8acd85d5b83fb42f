"""ground() on raycast pairs (bench.pairgen) whose refusals said the wrong thing."""

from __future__ import annotations


def test_a_mask_bled_onto_the_table_behind_does_not_make_the_correspondences_degenerate():
    """Raycast 2000:42, a bottle tipped over: the capture's mask bled onto the table far behind it, and the object's
    size read 382 mm (267 mm from its seen body). Its inliers' spread, 52 mm, is judged against the body's own size
    (degenerate under 0.15 of it): the pair is not refused as degenerate (it is refused by its view agreement)."""
    from bench.pairgen.generate import make_pair
    from pipeline.grounding.ground import ground
    from pipeline.grounding.types import GroundingConfig, GroundingInput
    from pipeline.perception.offline_features import OfflineFeatures

    p = make_pair(2000, 42)
    inp = GroundingInput(p.rgb0, p.depth0, p.mask0, p.rgb1, p.depth1, p.depth1_kind, p.mask1, p.intrinsics)
    motion = ground(inp, OfflineFeatures(), GroundingConfig(), T_base_camera=p.T_base_camera)
    assert (p.object_kind, p.motion_kind) == ("bottle", "tip")
    assert "degenerate" not in motion.reason, motion.reason
    assert motion.object_size_m > 0.3  # the bled size, which the other checks still scale with
