"""Gemini backends against a local fake server speaking the generateContent REST format."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fake_http import Reply, gemini_error, gemini_image, gemini_text, json_reply

from pipeline.config import GeminiConfig
from pipeline.reasoning.gemini import GeminiEditor, GeminiVLM, nearest_aspect_ratio
from pipeline.reasoning.providers import MissingApiKeyError, ProviderError
from pipeline.reasoning.types import EditRequest, ReflectionRequest


@pytest.fixture
def config(fake_server, monkeypatch) -> GeminiConfig:
    monkeypatch.setenv("FAKE_GEMINI_KEY", "k-123")
    return GeminiConfig(api_key_env="FAKE_GEMINI_KEY", base_url=fake_server.url, timeout_s=1.0, backoff_s=0.01)


def test_edit_success_sends_prompt_and_png_and_decodes_the_image(fake_server, config, scene_rgb):
    goal = np.full_like(scene_rgb, 7)
    fake_server.script(gemini_image(goal))
    result = GeminiEditor(config).edit(EditRequest(scene_rgb, "move the red block"))
    np.testing.assert_array_equal(result.rgb, goal)
    path, headers, body = fake_server.requests[0]
    assert path.endswith("/models/gemini-2.5-flash-image:generateContent")
    assert headers.get("x-goog-api-key") == "k-123"
    sent = json.loads(body)
    parts = sent["contents"][0]["parts"]
    assert parts[0]["text"] == "move the red block"
    inline = parts[1].get("inlineData") or parts[1]["inline_data"]
    assert (inline.get("mimeType") or inline.get("mime_type")) == "image/png"
    assert "IMAGE" in sent["generationConfig"]["responseModalities"]
    assert sent["generationConfig"]["imageConfig"]["aspectRatio"] == "4:3"  # the 64x48 input's


def test_aspect_ratio_request_follows_the_camera():
    assert nearest_aspect_ratio(1280, 720) == "16:9" and nearest_aspect_ratio(640, 640) == "1:1"


def test_429_then_success_is_retried(fake_server, config, scene_rgb):
    fake_server.script(gemini_error(429), gemini_error(503), gemini_image(scene_rgb))
    result = GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert result.rgb.shape == scene_rgb.shape
    assert len(fake_server.requests) == 3


def test_429_beyond_max_attempts_fails_as_rate_limited(fake_server, config, scene_rgb):
    fake_server.script(*[gemini_error(429)] * 3)
    with pytest.raises(ProviderError) as e:
        GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "rate_limited" and len(fake_server.requests) == 3


def test_400_is_not_retried(fake_server, config, scene_rgb):
    fake_server.script(gemini_error(400), gemini_image(scene_rgb))
    with pytest.raises(ProviderError) as e:
        GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "client" and e.value.fatal and len(fake_server.requests) == 1


def test_reply_without_image_part_is_a_recorded_failure(fake_server, config, scene_rgb):
    fake_server.script(gemini_text("I cannot edit this image."))
    with pytest.raises(ProviderError) as e:
        GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "no_image"
    assert "I cannot edit this image." in e.value.raw


def test_safety_block_is_a_refusal(fake_server, config, scene_rgb):
    fake_server.script(json_reply({"candidates": [], "promptFeedback": {"blockReason": "SAFETY"}}))
    with pytest.raises(ProviderError) as e:
        GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "refused" and "SAFETY" in str(e.value)


def test_malformed_http_body_is_a_clear_failure(fake_server, config, scene_rgb):
    fake_server.script(Reply(200, b"{not json"))
    with pytest.raises(ProviderError) as e:
        GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "malformed"


def test_timeout_fails_within_the_configured_time(fake_server, config, scene_rgb):
    fake_server.script(Reply(200, b"{}", delay_s=3.0))
    with pytest.raises(ProviderError) as e:
        GeminiEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "timeout"


def _reflection(rgb):
    mask = np.zeros(rgb.shape[:2], bool)
    mask[5:10, 5:10] = True
    return ReflectionRequest("put the red block on the plate", "prompt", rgb, rgb, rgb, mask, mask, "red block")


def test_reflect_uses_a_json_schema_and_parses_the_verdict(fake_server, config, scene_rgb):
    verdict = {"valid": False, "reasons": ["block floats"], "revised_prompt": "put it down on the plate"}
    fake_server.script(gemini_text(json.dumps(verdict)))
    v = GeminiVLM(config).reflect(_reflection(scene_rgb))
    assert not v.valid and v.reasons == ("block floats",) and v.revised_prompt == "put it down on the plate"
    sent = json.loads(fake_server.requests[0][2])
    assert sent["generationConfig"]["responseMimeType"] == "application/json"
    schema = sent["generationConfig"]["responseJsonSchema"]
    assert set(schema["required"]) == {"valid", "reasons", "revised_prompt"}
    assert "gemini-2.5-pro" in fake_server.requests[0][0]


def test_reflect_reply_outside_the_schema_is_malformed(fake_server, config, scene_rgb):
    fake_server.script(gemini_text("VALID: Yes"), gemini_text(json.dumps({"valid": "maybe"})))
    vlm = GeminiVLM(config)
    for _ in range(2):
        with pytest.raises(ProviderError) as e:
            vlm.reflect(_reflection(scene_rgb))
        assert e.value.kind == "malformed"


def test_enhance_returns_prompt_and_target(fake_server, config, scene_rgb):
    reply = {
        "edit_prompt": "The red block rests on the plate.",
        "target_object": "red block",
        "reference_object": "",
        "anchor_object": "",
    }
    fake_server.script(gemini_text(json.dumps(reply)))
    e = GeminiVLM(config).enhance(scene_rgb, "put the red block on the plate")
    assert e.prompt == "The red block rests on the plate." and e.target == "red block" and e.reference is None
    assert e.anchor is None
    schema = json.loads(fake_server.requests[-1][2])["generationConfig"]["responseJsonSchema"]
    assert "anchor_object" in schema["required"]


def test_enhance_names_the_moving_part_and_its_anchor(fake_server, config, scene_rgb):
    reply = {
        "edit_prompt": "The lid of the blue box is closed.",
        "target_object": "lid of the blue box",
        "reference_object": "",
        "anchor_object": "blue box",
    }
    fake_server.script(gemini_text(json.dumps(reply)))
    e = GeminiVLM(config).enhance(scene_rgb, "close the blue box")
    assert (e.target, e.anchor, e.reference) == ("lid of the blue box", "blue box", None)


def test_missing_key_fails_at_construction(monkeypatch):
    monkeypatch.delenv("NO_SUCH_GEMINI_KEY", raising=False)
    with pytest.raises(MissingApiKeyError, match="NO_SUCH_GEMINI_KEY"):
        GeminiEditor(GeminiConfig(api_key_env="NO_SUCH_GEMINI_KEY"))
