"""Reflection-through-Synthesis: acceptance, geometric checks, re-registration, failure reasons, override, record."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from pipeline.config import ChecksConfig, PipelineConfig
from pipeline.perception.depth import DepthEstimator, OfflineDepthEstimator, RelativeDepth
from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.reasoning.factory import build_reasoner, preflight
from pipeline.reasoning.interfaces import ImageEditor
from pipeline.reasoning.offline_editor import OfflineEditor
from pipeline.reasoning.offline_vlm import OfflineVLM
from pipeline.reasoning.providers import MissingApiKeyError, ProviderError
from pipeline.reasoning.reasoner import Reasoner, synthesize
from pipeline.reasoning.types import EditRequest, EditResult, ReasoningError

ON_PLATE = "put the red block on the white plate"


class ScriptedEditor(ImageEditor):
    """Returns prepared candidates in order (a stand-in for a generative editor's mistakes)."""

    def __init__(self, *images: np.ndarray) -> None:
        self.images = list(images)
        self.prompts: list[str] = []

    def edit(self, request: EditRequest) -> EditResult:
        self.prompts.append(request.prompt)
        if not self.images:
            raise ProviderError("no_image", "scripted editor: no candidate left", raw="text only")
        return EditResult(self.images.pop(0), raw="scripted")


class FlatDepth(DepthEstimator):
    def estimate(self, rgb):
        return RelativeDepth(np.ones(rgb.shape[:2], np.float32), "disparity")


def reasoner(editor: ImageEditor, config: PipelineConfig | None = None) -> Reasoner:
    seg = OfflineSegmenter()
    return Reasoner(editor, OfflineVLM(seg), seg, FlatDepth(), config or PipelineConfig())


@pytest.fixture(scope="module")
def composed(sim_view):
    """Offline goal candidates for the tabletop view, keyed by prompt."""
    frame, _, _ = sim_view
    editor = OfflineEditor(OfflineSegmenter())

    def make(prompt: str) -> np.ndarray:
        return editor.edit(EditRequest(frame.rgb, prompt, frame.depth, frame.intrinsics)).rgb

    return make


def test_default_profile_accepts_a_valid_goal_and_records_everything(sim_view, tmp_path):
    frame, masks, _ = sim_view
    goal = build_reasoner(PipelineConfig()).run(frame, ON_PLATE, record_dir=tmp_path / "rec")
    assert goal.validated and len(goal.iterations) == 1 and goal.verdicts[0].valid
    assert goal.prompts == ("put the red block on the white plate",)
    assert goal.mask_init.shape == goal.mask_goal.shape == frame.depth.shape
    assert (goal.mask_init & masks["red_block"]).sum() > 0.85 * masks["red_block"].sum()
    assert goal.depth_goal.kind == "disparity" and goal.depth_goal.values.dtype == np.float32
    assert set(goal.seconds) >= {"enhance", "segment", "edit", "checks", "reflect", "depth"}
    rec = tmp_path / "rec"
    for name in ("initial.png", "goal.png", "mask_init.png", "mask_goal.png", "goal_depth.npy", "enhancement.json"):
        assert (rec / name).exists(), name
    for name in ("prompt.txt", "edit_raw.txt", "candidate.png", "overlay.png", "verdict.json", "iteration.json"):
        assert (rec / "iter_1" / name).exists(), name
    summary = json.loads((rec / "reasoning.json").read_text())
    assert summary["ok"] and summary["validated"] and summary["accepted_iteration"] == 1
    with pytest.raises(FileExistsError):
        build_reasoner(PipelineConfig()).run(frame, ON_PLATE, record_dir=rec)


def test_overlay_blends_the_goal_object_at_alpha():
    init = np.zeros((4, 4, 3), np.uint8)
    goal = np.full((4, 4, 3), 200, np.uint8)
    mask = np.zeros((4, 4), bool)
    mask[1, 1] = True
    out = synthesize(init, goal, mask, 0.25)
    assert out[1, 1, 0] == 50 and out[0, 0, 0] == 0


def test_wrong_relation_is_rejected_each_iteration_and_the_run_fails(sim_view, composed, tmp_path):
    frame, _, _ = sim_view
    wrong = composed("put the red block right of the green cylinder")
    editor = ScriptedEditor(wrong, wrong, wrong)
    with pytest.raises(ReasoningError) as e:
        reasoner(editor).run(frame, "put the red block left of the green cylinder", record_dir=tmp_path)
    (reason,) = e.value.reasons  # the same reason each time: said once, with the iterations that gave it
    assert reason.startswith("iterations 1-3: 'left of' does not hold")
    assert not json.loads((tmp_path / "reasoning.json").read_text())["ok"]


def test_override_allows_the_last_unvalidated_goal_only_when_asked(sim_view, composed):
    frame, _, _ = sim_view
    wrong = composed("put the red block right of the green cylinder")
    goal = reasoner(ScriptedEditor(wrong, wrong)).run(
        frame, "put the red block left of the green cylinder", allow_unvalidated=True
    )
    assert not goal.validated and len(goal.iterations) == 3
    assert goal.iterations[2].failure_kind == "no_image"  # the third try had no image: the second is used
    assert goal.prompt == goal.iterations[1].prompt and not goal.iterations[1].verdict.valid
    with pytest.raises(ReasoningError):
        reasoner(ScriptedEditor(wrong)).run(frame, "put the red block left of the green cylinder")


def test_zoomed_candidate_is_reregistered_then_accepted(sim_view, composed):
    frame, _, _ = sim_view
    good = composed(ON_PLATE)
    h, w = good.shape[:2]
    zoomed = cv2.resize(good[9 : h - 9, 16 : w - 16], (w + 64, h + 36))  # 5 % zoom, other resolution
    goal = reasoner(ScriptedEditor(zoomed)).run(frame, ON_PLATE)
    it = goal.iterations[0]
    assert it.registered and goal.validated and "framing changed" in it.checks[0]
    assert goal.rgb_goal.shape == frame.rgb.shape


def test_zoomed_candidate_is_refused_when_configured(sim_view, composed):
    frame, _, _ = sim_view
    good = composed(ON_PLATE)
    h, w = good.shape[:2]
    zoomed = cv2.resize(good[9 : h - 9, 16 : w - 16], (w, h))
    config = PipelineConfig(reflection_iterations=1, checks=ChecksConfig(framing="refuse"))
    with pytest.raises(ReasoningError) as e:
        reasoner(ScriptedEditor(zoomed), config).run(frame, ON_PLATE)
    assert "framing changed" in e.value.reasons[0] and "zoom" in e.value.reasons[0]


def test_checks_catch_missing_duplicated_unmoved_target_and_moved_objects(sim_view, composed):
    frame, masks, _ = sim_view
    good = composed(ON_PLATE)
    missing = frame.rgb.copy()
    red = masks["red_block"]
    missing[red] = cv2.inpaint(frame.rgb, red.astype(np.uint8) * 255, 5, cv2.INPAINT_TELEA)[red]
    duplicated = good.copy()
    duplicated[red] = frame.rgb[red]  # the block on the plate and still at its old place
    others_moved = composed("push the blue block left by 10 cm")
    others_moved = np.where(masks["red_block"][..., None] | _near(good, frame.rgb), good, others_moved)
    editor = ScriptedEditor(missing, duplicated, frame.rgb.copy())
    with pytest.raises(ReasoningError) as e:
        reasoner(editor).run(frame, ON_PLATE)
    assert "missing" in e.value.reasons[0]
    assert "appears 2 times" in e.value.reasons[1]
    assert "did not change" in e.value.reasons[2]
    with pytest.raises(ReasoningError) as e:
        reasoner(ScriptedEditor(others_moved), PipelineConfig(reflection_iterations=1)).run(frame, ON_PLATE)
    assert "background changed outside the target" in e.value.reasons[0]


def _near(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pixels where two images differ (the red block's move), grown a little."""
    diff = (np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 0).astype(np.uint8)
    return cv2.dilate(diff, np.ones((9, 9), np.uint8)).astype(bool)[..., None]


def test_build_reasoner_fails_at_start_up_without_keys(monkeypatch):
    monkeypatch.delenv("GEMINI_API_KEY", raising=False)
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    config = PipelineConfig(editor="gemini", vlm="openai")
    problems = preflight(config)
    assert len(problems) == 2 and "GEMINI_API_KEY" in problems[0] and "OPENAI_API_KEY" in problems[1]
    with pytest.raises(MissingApiKeyError, match="GEMINI_API_KEY"):
        build_reasoner(config)
    assert preflight(PipelineConfig()) == []


def test_offline_depth_is_wired_to_the_offline_editor():
    r = build_reasoner(PipelineConfig())
    assert isinstance(r.depth, OfflineDepthEstimator) and r.editor.depth_registry is r.depth


def test_a_reason_given_by_several_iterations_is_said_once_with_them():
    from pipeline.reasoning.reasoner import _by_iterations
    from pipeline.reasoning.types import Iteration, Verdict

    missing = Verdict(False, ("target 'cylinder' missing from the candidate",))
    iterations = [
        Iteration(1, "p", verdict=missing),
        Iteration(2, "p", failure="timeout after 30 s"),
        Iteration(3, "p", verdict=missing),
        Iteration(4, "p", verdict=missing),
    ]
    assert _by_iterations(iterations) == [
        "iterations 1, 3, 4: target 'cylinder' missing from the candidate",
        "iteration 2: timeout after 30 s",
    ]
    assert _by_iterations(iterations[2:]) == ["iterations 3-4: target 'cylinder' missing from the candidate"]


def test_of_several_matches_in_the_goal_image_the_one_like_the_target_is_taken():
    from pipeline.perception.segmenter import Detection, box_of
    from pipeline.reasoning.checks import like_the_target

    target0, moved, bottle, ball, twin = (np.zeros((60, 80), bool) for _ in range(5))
    target0[10:20, 10:20] = True  # 100 px, green
    moved[30:40, 50:60] = True  # the target moved: its size and colour
    bottle[5:45, 30:45] = True  # a green bottle, six times larger
    ball[45:55, 5:15] = True  # a ball of its size, another green
    twin[45:55, 65:75] = True  # a block of its size and colour, already there
    scene = np.full((60, 80, 3), 128, np.uint8)
    scene[bottle], scene[ball], scene[twin] = (30, 100, 40), (20, 120, 20), (60, 200, 60)
    initial, goal = scene.copy(), scene.copy()
    initial[target0], goal[moved] = (60, 200, 60), (60, 200, 60)
    det = lambda m: Detection(m, 1.0, box_of(m), "green")  # noqa: E731
    (taken,) = like_the_target([det(bottle), det(moved)], initial, target0, goal)
    assert taken.mask is moved
    (taken,) = like_the_target([det(twin), det(moved)], initial, target0, goal)  # the twin was there: not it
    assert taken.mask is moved
    assert len(like_the_target([det(bottle), det(ball)], initial, target0, goal)) == 2  # neither is the target
    goal[target0] = (60, 200, 60)
    twice = [det(moved), det(target0)]  # drawn again, left where it was too: refused as two
    assert len(like_the_target(twice, initial, target0, goal)) == 2


def test_a_target_put_on_an_object_of_its_colour_is_cut_from_the_region_they_make():
    """A cyan ball put on a cyan plate is one colour region with the plate in the goal image (and after the run):
    the target is what is new in it, not the plate that was there before."""
    from pipeline.perception.segmenter import Detection, box_of
    from pipeline.reasoning.checks import like_the_target

    yy, xx = np.mgrid[0:60, 0:80]
    ball0 = (yy - 45) ** 2 + (xx - 12) ** 2 <= 36
    plate = ((yy - 20) / 10.0) ** 2 + ((xx - 50) / 18.0) ** 2 <= 1.0
    ball = (yy - 17) ** 2 + (xx - 50) ** 2 <= 36  # on the plate
    initial = np.full((60, 80, 3), 150, np.uint8)
    initial[plate], initial[ball0] = (20, 110, 120), (70, 210, 220)
    goal = initial.copy()
    goal[ball0], goal[ball] = (150, 150, 150), (70, 210, 220)
    (taken,) = like_the_target([Detection(plate | ball, 1.0, box_of(plate | ball), "cyan")], initial, ball0, goal)
    near_ball = (yy - 17) ** 2 + (xx - 50) ** 2 <= 9**2  # the change is measured blurred: 2-3 px around it
    assert (taken.mask & ball).sum() >= 0.9 * ball.sum() and not (taken.mask & ~near_ball).any()
    alone = Detection(ball, 1.0, box_of(ball), "cyan")  # a region that is the target alone is kept as it is
    assert like_the_target([alone], initial, ball0, goal)[0].mask is ball
