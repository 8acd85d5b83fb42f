"""The full loop with the Gemini backends against the fake server: reflector rejects, revised prompt, accept."""

from __future__ import annotations

import json

import numpy as np
from fake_http import gemini_error, gemini_image, gemini_text
from test_reasoning_loop import FlatDepth

from pipeline.config import GeminiConfig, PipelineConfig
from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.reasoning.gemini import GeminiEditor, GeminiVLM
from pipeline.reasoning.offline_editor import OfflineEditor
from pipeline.reasoning.reasoner import Reasoner
from pipeline.reasoning.types import EditRequest


def test_reflector_rejection_revises_the_prompt_and_everything_is_recorded(
    sim_view, fake_server, monkeypatch, tmp_path
):
    frame, _, _ = sim_view
    compose = OfflineEditor(OfflineSegmenter())

    def candidate(prompt: str) -> np.ndarray:
        return compose.edit(EditRequest(frame.rgb, prompt, frame.depth, frame.intrinsics)).rgb

    enhancement = {
        "edit_prompt": "The red block sits on the plate.",
        "target_object": "red block",
        "reference_object": "white plate",
        "anchor_object": "",
    }
    rejected = {
        "valid": False,
        "reasons": ["the block is beside the cylinder"],
        "revised_prompt": "Put it ON the plate.",
    }
    accepted = {"valid": True, "reasons": ["on the plate"], "revised_prompt": ""}
    fake_server.script(
        gemini_text(json.dumps(enhancement)),
        gemini_image(candidate("put the red block right of the green cylinder")),
        gemini_text(json.dumps(rejected)),
        gemini_error(429),
        gemini_image(candidate("put the red block on the white plate")),
        gemini_text(json.dumps(accepted)),
    )
    monkeypatch.setenv("GEMINI_API_KEY", "k")
    config = GeminiConfig(base_url=fake_server.url, timeout_s=2.0, backoff_s=0.01)
    seg = OfflineSegmenter()
    reasoner = Reasoner(GeminiEditor(config), GeminiVLM(config), seg, FlatDepth(), PipelineConfig())
    goal = reasoner.run(frame, "put the red block on the plate", record_dir=tmp_path)

    assert goal.validated and goal.prompts == ("The red block sits on the plate.", "Put it ON the plate.")
    assert goal.verdicts[0].reasons == ("the block is beside the cylinder",) and goal.verdicts[1].valid
    assert len(fake_server.requests) == 6
    edit_requests = [json.loads(body) for path, _, body in fake_server.requests if "flash-image" in path]
    assert edit_requests[-1]["contents"][0]["parts"][0]["text"] == "Put it ON the plate."
    iter1 = tmp_path / "iter_1"
    assert "Here is the edited image." in (iter1 / "edit_raw.txt").read_text()
    assert json.loads((iter1 / "verdict.json").read_text())["raw"] == json.dumps(rejected)
    assert (iter1 / "overlay.png").exists() and (tmp_path / "iter_2" / "overlay.png").exists()
    assert json.loads((tmp_path / "reasoning.json").read_text())["accepted_iteration"] == 2
