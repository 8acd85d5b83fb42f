"""Spatial grounding: the object's 3D motion from the initial RGB-D view to the generated goal view.

Steps: align the goal's relative depth on the background; lift both object masks to camera-frame clouds;
match object pixels by dense features (mutual, thresholded, restricted to the goal mask); keep matches that
preserve pairwise distances; Umeyama similarity in RANSAC with a threshold scaled to the object; optional ICP
on the masked clouds; refuse, with a reason, whenever a check fails.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import cv2
import numpy as np
from scipy.spatial import cKDTree

from pipeline.contact.symmetry import revolved
from pipeline.grounding.articulation import HingeNotFound, best_turn, find_hinge
from pipeline.grounding.box_outline import face_lean_deg, turned_to_outline
from pipeline.grounding.disc_outline import is_plate, tipped_disc
from pipeline.grounding.handle import (
    HandledBody,
    ends_by_print,
    handle_hypotheses,
    handled_body,
    hidden_handle_turned,
    turn_by_handle,
)
from pipeline.grounding.handle_outline import hidden_handle_spun, spun_to_outline
from pipeline.grounding.hypotheses import (
    axis_hypotheses,
    ball_hypotheses,
    end_for_end,
    face_hypotheses,
    footprint_hypotheses,
    spun,
    sweep_hypotheses,
)
from pipeline.grounding.lean_outline import leaned_to_outline
from pipeline.grounding.matching import Matches, match_pixels, pairwise_consistency
from pipeline.grounding.outline_fit import goal_outline
from pipeline.grounding.outline_place import placed_on_outline
from pipeline.grounding.prepare import Prepared, object_size, prepare, refuse
from pipeline.grounding.ray_rest import (
    MIN_GAP_M,
    UPRIGHT_DEG,
    ball_surface,
    down_to_support,
    out_of_support,
    rest_along_ray,
    set_down,
)
from pipeline.grounding.seen_symmetry import as_seen, off_support, seen_box, shape_symmetry
from pipeline.grounding.seen_turns import read_turns
from pipeline.grounding.select import Selected, fine_tolerance, select_motion
from pipeline.grounding.silhouette import axis_into_plane, axis_turned_to_outline, onto_ray, silhouette_ray
from pipeline.grounding.tilt import LYING_DEG, NO_BETTER, kept_level, ranks_above, tilt_deg
from pipeline.grounding.types import GroundingConfig, GroundingInput, ObjectMotion, SeenSymmetry
from pipeline.grounding.umeyama import Similarity, ransac_similarity
from pipeline.grounding.verify import view_consistency
from pipeline.grounding.workers import one_thread_each, workers
from pipeline.perception.features import FeatureExtractor

MAX_CONSISTENCY_MATCHES = 1500
SET_ON_FACE_DEG = 0.01  # a box the outline set on a face leans less than this off the table ...
SET_DOWN_LEAN_DEG = 5.0  # ... and is set down on the table where it had leaned this much (box_outline.face_down)
OUTLINE_PX = 4  # a mask's outline is this many pixels off at most (a segmenter's dilation, a ragged edge)
ALIGNED_RESIDUAL_OF_THRESHOLD = 0.5  # an inlier RMS above this share of the inlier threshold is no alignment
MAX_ACROSS_REL = 1.0  # the outline moving the goal further across the ray than the object's size: they disagree


def ground(
    inp: GroundingInput,
    features: FeatureExtractor,
    config: GroundingConfig | None = None,
    T_base_camera: np.ndarray | None = None,
    hints: Sequence[Similarity] = (),
) -> ObjectMotion:
    """ObjectMotion (x_goal = R x_init + t, camera frame) or a refusal with its reason. `hints`: motions known to
    be likely (select_motion), taken when the views cannot tell them from the best found."""
    with one_thread_each():  # its steps run side by side on the cores instead (workers.py)
        return _ground(inp, features, config or GroundingConfig(), T_base_camera, hints)


def _ground(
    inp: GroundingInput,
    features: FeatureExtractor,
    cfg: GroundingConfig,
    T_base_camera: np.ndarray | None,
    hints: Sequence[Similarity],
) -> ObjectMotion:
    if cfg.work_width_px is not None and cfg.work_width_px < inp.intrinsics.width:
        inp = inp.resized(cfg.work_width_px)
    K = inp.intrinsics
    pp = prepare(inp, cfg, T_base_camera)
    if isinstance(pp, ObjectMotion):
        return pp
    view0, view1, size, align = pp.view0, pp.view1, pp.size, pp.align
    common = {"depth_residual_m": align.residual_m, "T_base_camera": T_base_camera, "object_size_m": size}
    if inp.anchor0 is not None:  # a part that turns about where it meets its anchor (a lid on its box)
        return _ground_hinged(inp, pp, cfg, common)
    if pp.hue_overlap is not None and pp.hue_overlap < cfg.min_hue_overlap:  # geometry alone cannot see it
        return refuse(
            f"the goal's object is not coloured like the initial one: their hues share {pp.hue_overlap:.0%} "
            f"(need {cfg.min_hue_overlap:.0%}); is the goal mask on another object?",
            **common,
        )
    rng = np.random.default_rng(cfg.seed)
    threshold = max(cfg.inlier_min_m, cfg.inlier_rel * size)
    up = _up_direction(pp.points0, ~(inp.mask0 | inp.mask1) & np.isfinite(pp.depth0), T_base_camera, rng)
    with workers(1) as pool:  # the features' search alongside the geometric hypotheses
        by_features = pool.submit(_by_features, inp, pp, features, size, threshold, cfg, rng)
        sweep = sweep_hypotheses(view0, view1, K, up, cfg.sweep_hypotheses, size)
        # each view's points above what it stands on: the object's own, without the support a mask bleeds onto
        seen0 = off_support(view0.cloud, view0.normals, pp.points0, inp.mask0, up)
        seen1 = off_support(view1.cloud, view1.normals, pp.points1, inp.mask1, up)
        on_table = footprint_hypotheses(seen0[0], seen1[0], up) + handle_hypotheses(seen0, seen1, up)  # about up
        shape = shape_symmetry(*seen0, up)  # what the capture's shape cannot show
        geometric = face_hypotheses(view0, view1) + on_table + ball_hypotheses(view0, view1) + sweep
        geometric += axis_hypotheses(view0, view1, K, shape, size)
        m, fits = by_features.result()
    common["matches"] = len(m.src_px)
    candidates = fits + geometric
    chosen = select_motion(candidates, view0, view1, K, size, cfg, hints)
    middle = pp.cloud0.mean(axis=0)  # the seen points' middle, as at the start

    def better_twin(winner: Selected, twins: list[Similarity]) -> Selected:
        """The best of the winner's `twins`, refined and scored alike, where it ranks above the winner."""
        if not twins:
            return winner
        twin = select_motion(twins, view0, view1, K, size, cfg.model_copy(update={"refine_top": 3}))
        return twin if _ranks_above(twin, winner, up) else winner

    if not chosen.hinted:  # the winner turned end for end: taken where it explains the views better
        chosen = better_twin(chosen, end_for_end(chosen.motion, shape, view0.cloud, view1.cloud))
    if not chosen.hinted and tilt_deg(chosen.motion.R, up) > 90.0 + LYING_DEG:  # turned over: its twins kept up too
        over = SeenSymmetry("revolution", middle, axis=up)  # end for end about the vertical
        chosen = better_twin(chosen, end_for_end(chosen.motion, over, view0.cloud, view1.cloud))
    if chosen.score < cfg.min_view_score and not chosen.hinted and not inp.depth1_measured and shape.axis is not None:
        # nothing explains the views: a flat body tipped onto its rim, read off its goal outline (disc_outline.py)
        scene = _scene_around(pp.points0, inp.mask0)
        tipped = tipped_disc(view0, view1, K, size, cfg, (shape.centre, shape.axis), seen0[0], scene, up, inp.mask1)
        if tipped is not None and tipped.score >= cfg.min_view_score:
            chosen = tipped
    if chosen.score < cfg.min_view_score and not chosen.hinted:  # still not borne out: spun about its axis, which
        chosen = better_twin(chosen, spun(chosen.motion, shape))  # its shape does not show (hypotheses.spun)
    sim, view_score, hinted = chosen.motion, chosen.score, chosen.hinted
    fine = fine_tolerance(size, cfg)
    handled = handled_body(seen0, up) if shape.kind == "none" and not hinted else None
    if handled is not None:  # a standing body with a handle: where its handle shows tells its turn, its print its ends
        sim = ends_by_print(turn_by_handle(sim, handled, view1, K, fine), handled, view0, view1, K, fine)
    views = [(inp.rgb0, inp.mask0, pp.points0), (inp.rgb1, inp.mask1, pp.points1)]
    symmetry, turns_margin = as_seen(shape, views), None
    if shape.kind != "none" and symmetry.kind == "none" and not hinted:  # a print: does it tell the shape's twins?
        sim, symmetry, turns_margin = read_turns(sim, shape, view0, view1, K, fine)
    if symmetry.axis is not None and not hinted:  # its turn about its axis unread: a handle the capture hid tells it
        behind = _hidden_handle(sim, shape, seen0[0], seen1[0], up, inp, pp)
        if behind is not None:
            sim, symmetry = behind, SeenSymmetry("none", shape.centre)

    def geometry(motion: Similarity) -> float:  # the views' geometric agreement with a motion
        return view_consistency(motion, view0, view1, K, fine).geometry

    # what is set on its support, the least correction taken and the point whose ray it moves along (ray_rest)
    body0, min_gap, through = pp.cloud0, MIN_GAP_M, None
    # `placed`: the motion moved across the ray to where the goal image shows the object (silhouette.py); the checks
    # below judge `sim`, the registration, on the goal cloud it was fitted to: the model's depth the move corrects
    # would refuse it (a ball put back on its outline's ray kept 2 of its 430 points within 4.5 mm of the goal cloud)
    if symmetry.kind == "ball" and not hinted:  # no turn shows: its motion is its centre's shift, nothing tilts it
        sim = Similarity(sim.scale, np.eye(3), sim.apply(symmetry.centre[None])[0] - sim.scale * symmetry.centre)
        ray = None if inp.depth1_measured else silhouette_ray(inp.mask1, K)
        # a model's depth can put a ball to one side of where its image shows it
        placed = sim if ray is None else onto_ray(sim, symmetry.centre, ray)
        radius = float(np.median(np.linalg.norm(pp.cloud0 - symmetry.centre, axis=1)))
        body0, min_gap = ball_surface(symmetry.centre, radius), 0.0
    elif not hinted:  # a tilt the views do not show better than none is not taken
        sim = placed = kept_level(sim, up, shape.centre, geometry)
        if shape.axis is not None and not inp.depth1_measured:  # a model's depth can put it to one side
            if tilt_deg(sim.R, up) > UPRIGHT_DEG:  # a tipped body's axis turned across the ray to its outline's
                turned = axis_turned_to_outline(sim, _on_axis(middle, shape), shape.axis, inp.mask1, K)
                # unless the views show it worse: the start's axis read some degrees off, the outline turns a right
                # motion that far (a can lying across the view: 0.8 -> 8.9 deg, its agreement 0.82 -> 0.36)
                if turned is not sim and geometry(turned) >= geometry(sim) - NO_BETTER:
                    placed = turned
            in_plane = axis_into_plane(placed, shape.centre, shape.axis, inp.mask1, K)
            if in_plane is not None:
                placed, through = in_plane, shape.centre
    else:
        placed = sim
    across = float(np.linalg.norm(placed.apply(middle[None]) - sim.apply(middle[None])))  # where it moved the body
    dist, _ = cKDTree(view1.cloud).query(sim.apply(view0.cloud))
    inliers = dist < threshold
    n_in = int(inliers.sum())
    common["inliers"] = n_in
    ratio = n_in / len(dist)
    if n_in < cfg.min_inliers or ratio < cfg.min_inlier_ratio:
        return refuse(
            f"too few inliers: {n_in} of {len(dist)} object points within {threshold * 1000:.1f} mm of the goal "
            f"({ratio:.0%}); need {cfg.min_inliers} and {cfg.min_inlier_ratio:.0%}",
            **common,
        )
    spread = _second_extent(view0.cloud[inliers])
    body_size = object_size(seen0[0])  # the body's own: a mask's bleed onto the table far behind it is no part of it
    if spread < cfg.min_spread_rel * body_size:
        return refuse(
            f"degenerate correspondences: inliers lie nearly on a line (second extent {spread * 1000:.1f} mm, "
            f"the object's seen body {body_size * 1000:.0f} mm)",
            **common,
        )
    lo, hi = cfg.scale_range
    if not lo <= sim.scale <= hi:
        return refuse(
            f"implausible scale {sim.scale:.3f} between goal and initial object (allowed {lo}-{hi})", **common
        )
    rms = float(np.sqrt(np.mean(dist[inliers] ** 2)))
    # a small object is judged no finer than its inlier threshold allows: points within it spread at random would
    # give an RMS of 0.77 of it, an aligned fit's sensor noise well under half (a 31 mm ball at 1.6 mm was refused)
    residual_limit = max(cfg.max_registration_residual_rel * size, ALIGNED_RESIDUAL_OF_THRESHOLD * threshold)
    if rms > residual_limit:
        return refuse(
            f"registration residual {rms * 1000:.1f} mm too large for a {size * 1000:.0f} mm object "
            f"(limit {residual_limit * 1000:.1f} mm)",
            residual_m=rms,
            **common,
        )
    if view_score < cfg.min_view_score:
        return refuse(
            f"the motion does not explain the images: view agreement {view_score:.2f} (need {cfg.min_view_score})",
            residual_m=rms,
            **common,
        )
    if across > MAX_ACROSS_REL * size:
        return refuse(
            f"the goal image shows the object {across * 1000:.0f} mm across the camera ray from where its goal depth "
            f"puts it (limit {MAX_ACROSS_REL * size * 1000:.0f} mm, its size): the goal's mask or depth is off",
            residual_m=rms,
            **common,
        )
    rested = 0.0
    if not inp.depth1_measured and not hinted:  # a model's goal depth: its distance along the ray from the support
        spin = None if shape.axis is None else (shape.centre, shape.axis)  # its turns about its axis look alike
        scene = _scene_around(pp.points0, inp.mask0)
        placed, rested = rest_along_ray(placed, body0, scene, up, min_gap, through, spin)
        placed = _on_goal_outline(placed, shape, seen0, handled, up, inp, pp, size, scene, geometry)
    t_rigid = placed.apply(middle[None])[0] - placed.R @ middle  # the middle lands where the similarity puts it
    confidence = float(view_score * min(1.0, n_in / 30) * np.exp(-rms / threshold))
    return ObjectMotion(
        ok=True,
        reason="",
        R=placed.R,
        t=t_rigid,
        scale=placed.scale,
        residual_m=rms,
        confidence=confidence,
        details={
            "depth_alignment": align.summary(),
            "view_score": view_score,
            "view_ranked": chosen.ranked,  # what it won on against the other hypotheses (select.Selected.ranked)
            "threshold_m": threshold,
            **({"hint_taken": True} if hinted else {}),
            **({"turns_margin": turns_margin} if turns_margin is not None else {}),
            **({"moved_across_ray_m": across} if across else {}),
            **({"rested_along_ray_m": rested} if rested else {}),
        },
        symmetry=symmetry,
        **common,
    )


def _ground_hinged(inp: GroundingInput, pp: Prepared, cfg: GroundingConfig, common: dict) -> ObjectMotion:
    """The turn of a hinged part about the line where it meets its anchor (pipeline.grounding.articulation)."""
    points0, points1, valid0, valid1, size = pp.points0, pp.points1, pp.valid0, pp.valid1, pp.size
    try:
        hinge = find_hinge(points0[valid0], points0[inp.anchor0 & np.isfinite(points0[..., 2])])
    except HingeNotFound as e:
        return refuse(f"hinged target: {e}", **common)
    cloud0, cloud1 = points0[valid0], points1[valid1]
    angle, agreement = best_turn(hinge, cloud0, cloud1, inp.mask0, inp.mask1, inp.intrinsics)
    motion = hinge.turn(angle)
    dist, _ = cKDTree(cloud1).query(motion.apply(cloud0))
    threshold = max(cfg.inlier_min_m, cfg.inlier_rel * size)
    inliers = dist < threshold
    rms = float(np.sqrt(np.mean(dist[inliers] ** 2))) if inliers.any() else float("nan")
    common |= {"inliers": int(inliers.sum()), "residual_m": rms}
    if agreement < cfg.min_view_score:
        return refuse(
            f"no turn about the hinge explains the images: silhouette agreement {agreement:.2f} at the best angle "
            f"{np.degrees(angle):.0f} deg (need {cfg.min_view_score})",
            **common,
        )
    return ObjectMotion(
        ok=True,
        reason="",
        R=motion.R,
        t=motion.t,
        confidence=agreement,
        details={
            "hinge_point_m": hinge.point.tolist(),
            "hinge_axis": hinge.axis.tolist(),
            "hinge_angle_deg": float(np.degrees(angle)),
            "silhouette_agreement": agreement,
            "threshold_m": threshold,
        },
        **common,
    )


def _by_features(
    inp: GroundingInput,
    pp: Prepared,
    features: FeatureExtractor,
    size: float,
    threshold: float,
    cfg: GroundingConfig,
    rng: np.random.Generator,
) -> tuple[Matches, list[Similarity]]:
    """The feature matches between the two objects' pixels and the motions they support (_feature_hypotheses)."""
    src = np.argwhere(pp.valid0)[:, ::-1]
    if len(src) > cfg.max_source_pixels:
        src = src[rng.choice(len(src), cfg.max_source_pixels, replace=False)]
    dst = np.argwhere(pp.valid1)[:, ::-1]
    m = match_pixels(
        features,
        inp.rgb0,
        src,
        inp.rgb1,
        dst,
        pp.points0,
        pp.points1,
        mutual=cfg.mutual,
        min_similarity=cfg.min_similarity,
    )
    return m, _feature_hypotheses(pp.points0, pp.points1, m, size, threshold, cfg, rng)


def _feature_hypotheses(
    points0: np.ndarray,
    points1: np.ndarray,
    m: Matches,
    size: float,
    threshold: float,
    cfg: GroundingConfig,
    rng: np.random.Generator,
) -> list[Similarity]:
    """Similarity hypotheses from the feature matches: distance-consistent matches, then RANSAC. Empty when the
    features give too little (uniform objects, weak backends): the geometric sweep then carries the search and
    the view check decides whether to refuse."""
    if len(m.src_px) < cfg.min_inliers:
        return []
    P = points0[m.src_px[:, 1], m.src_px[:, 0]]
    Q = points1[m.dst_px[:, 1], m.dst_px[:, 0]]
    if len(P) > MAX_CONSISTENCY_MATCHES:
        keep = rng.choice(len(P), MAX_CONSISTENCY_MATCHES, replace=False)
        P, Q = P[keep], Q[keep]
    support = pairwise_consistency(P, Q, cfg.consistency_rel * size, cfg.scale_range)
    keep = support >= cfg.min_consistency * support.max()
    fits = ransac_similarity(
        P[keep],
        Q[keep],
        threshold,
        iterations=cfg.ransac_iterations,
        min_sample_spread_m=0.1 * size,
        scale_range=cfg.scale_range,
        top_k=cfg.hypotheses,
        seed=cfg.seed,
    )
    lo, hi = cfg.scale_range
    return [f.transform for f in fits if lo <= f.transform.scale <= hi]  # refits can drift out of range


def _on_goal_outline(
    motion: Similarity,
    shape: SeenSymmetry,
    seen0: tuple[np.ndarray, np.ndarray],
    handled: HandledBody | None,
    up: np.ndarray,
    inp: GroundingInput,
    pp: Prepared,
    size: float,
    scene: np.ndarray,
    geometry: Callable[[Similarity], float],
) -> Similarity:
    """A model's goal turned and moved along the table to where the goal mask's outline shows it, for bodies whose
    whole shape the capture gives: a box turned about the vertical (box_outline.py; where that sets it on a face, set
    down on the table in `scene`, the capture's other points) and moved, a handled body spun about its axis
    (handle_outline.py) and moved, a body of revolution moved (outline_place.py), a tipped one leaned first
    toward or away from the camera (lean_outline.py). The outline does not depend on the
    model's depth, which leans a small box off its face, lays a mug's handle along a grown mask and puts a large pan
    or a bowl centimetres off. A tipped one is then raised out of the table where the model's depth sank it
    (ray_rest.out_of_support)."""
    box = seen_box(*seen0) if shape.kind == "box" else None
    round_body = shape.axis is not None and handled is None  # a ball has no axis: ray_rest placed it
    if box is None and handled is None and not round_body:
        return motion
    outline = goal_outline(inp.mask1, pp.depth1, inp.intrinsics)
    if outline is None:
        return motion
    if box is not None:
        turned = turned_to_outline(motion, box, up, outline)
        if face_lean_deg(turned, box, up) < SET_ON_FACE_DEG and face_lean_deg(motion, box, up) >= SET_DOWN_LEAN_DEG:
            # set on a face from a lean ray_rest took for a tip: it stands on the table (its seen corners' bottom is
            # a few millimetres up, cut at the support: not worth it for a small lean, whose height ray_rest set)
            turned = set_down(turned, box.corners, box.centre, scene, up) or turned
        motion, whole, centre = turned, box.corners, box.centre
    elif handled is not None:
        whole, centre = handled.whole(), handled.centre
        motion = spun_to_outline(motion, handled, whole, outline)
    else:
        axis = shape.axis / np.linalg.norm(shape.axis)
        whole, centre = revolved(seen0[0], shape.centre, axis), shape.centre
    whole = down_to_support(whole, scene, up)  # its seen points stop above the table: its outline does not
    if box is None and handled is None and tilt_deg(motion.R, up) > UPRIGHT_DEG:  # a tipped body of revolution
        leaned = leaned_to_outline(motion, whole, centre, axis, outline)
        # a plate lying on the table in the capture shows its lean in its outline; a can, a bottle or a bowl less
        # than their depth's warp hides it: their lean is taken where the views agree with it no less
        plate = _along_vertical(axis, up) and is_plate(seen0, centre, axis)
        if leaned is not motion and (plate or geometry(leaned) >= geometry(motion)):
            motion = leaned
    placed = placed_on_outline(motion, whole, centre, up, outline, size)
    if tilt_deg(placed.R, up) <= UPRIGHT_DEG:  # upright: ray_rest kept its height above the support
        return placed
    return out_of_support(placed, whole, centre, scene, up)


def _up_direction(
    points: np.ndarray, background: np.ndarray, T_base_camera: np.ndarray | None, rng: np.random.Generator
) -> np.ndarray:
    """The table normal in the camera frame: from the calibration, else the dominant plane of the points (H, W, 3)
    of the `background` pixels (picked out only then: a copy of most of the image, 3 ms a pair)."""
    if T_base_camera is not None:
        return np.asarray(T_base_camera)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    import open3d as o3d

    background = points[background]
    pts = background[rng.choice(len(background), min(len(background), 5000), replace=False)]
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts.astype(np.float64)))
    (a, b, c, _), _ = pcd.segment_plane(0.01, 3, 200)
    n = np.array([a, b, c]) / np.linalg.norm([a, b, c])
    return -n if n @ pts.mean(axis=0) > 0 else n


def _hidden_handle(
    motion: Similarity,
    shape: SeenSymmetry,
    seen0: np.ndarray,
    seen1: np.ndarray,
    up: np.ndarray,
    inp: GroundingInput,
    pp: Prepared,
) -> Similarity | None:
    """`motion` spun to where the goal outline (handle_outline.hidden_handle_spun), or else the goal's points facing
    the camera (`seen1`: above the support; handle.hidden_handle_turned), show a handle that a body of revolution
    standing in the capture (`seen0`: its points above the support) hid behind it, or None; for a goal
    left standing only (a tipped body's outline, its goal depth off, fits a fin anywhere: a raycast plate)."""
    if shape.axis is None or not _along_vertical(shape.axis, up) or tilt_deg(motion.R, up) > UPRIGHT_DEG:
        return None
    outline = goal_outline(inp.mask1, pp.depth1, inp.intrinsics)
    a = up / np.linalg.norm(up)
    if outline is not None:
        found = hidden_handle_spun(motion, shape.centre, a, revolved(seen0, shape.centre, a), outline)
        if found is not None:
            return found
    return hidden_handle_turned(motion, shape.centre, a, seen0, seen1)


def _along_vertical(axis: np.ndarray, up: np.ndarray) -> bool:
    """Whether a body's `axis` (camera frame, as `up`) lies within UPRIGHT_DEG of the vertical: it stands (or lies
    flat) on the table."""
    return abs(float(axis @ up)) >= np.cos(np.radians(UPRIGHT_DEG)) * np.linalg.norm(axis) * np.linalg.norm(up)


def _ranks_above(a: Selected, b: Selected, up: np.ndarray) -> bool:
    """Whether motion `a` is taken over `b`: what they rank on (select.Selected.ranked), one that turns the object
    over held to a margin against one that keeps its top up (tilt.ranks_above)."""
    return ranks_above(a.ranked, a.motion.R, b.ranked, b.motion.R, up)


def _scene_around(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The capture's points (camera frame) other than the object's, its outline's few pixels left out too; every
    other pixel each way (a support's median height needs no more)."""
    near = cv2.dilate(mask.astype(np.uint8), np.ones((2 * OUTLINE_PX + 1,) * 2, np.uint8)).astype(bool)
    keep = ~near & np.isfinite(points[..., 2])
    return points[::2, ::2][keep[::2, ::2]]


def _on_axis(point: np.ndarray, shape: SeenSymmetry) -> np.ndarray:
    """The point of a body of revolution's axis nearest `point` (the axis's own point may lie far along it)."""
    axis = shape.axis / np.linalg.norm(shape.axis)
    return shape.centre + float((point - shape.centre) @ axis) * axis


def _second_extent(points: np.ndarray) -> float:
    """Extent [m] of a cloud along its second principal axis (uniform-spread estimate, sqrt(12) sigma)."""
    if len(points) < 3:
        return 0.0
    ev = np.linalg.svd(points - points.mean(axis=0), compute_uv=False) / np.sqrt(len(points))
    return float(np.sqrt(12.0) * ev[1])
