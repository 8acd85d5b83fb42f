"""OpenAI backends against a local fake server speaking the images/edits and chat/completions REST formats."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fake_http import Reply, json_reply, openai_chat, openai_error, openai_image

from pipeline.config import OpenAIConfig
from pipeline.reasoning.openai_backend import OpenAIEditor, OpenAIVLM
from pipeline.reasoning.providers import MissingApiKeyError, ProviderError
from pipeline.reasoning.types import EditRequest, ReflectionRequest


@pytest.fixture
def config(fake_server, monkeypatch) -> OpenAIConfig:
    monkeypatch.setenv("FAKE_OPENAI_KEY", "sk-test")
    return OpenAIConfig(api_key_env="FAKE_OPENAI_KEY", base_url=fake_server.url + "/v1", timeout_s=1.0, backoff_s=0.01)


def test_edit_success_posts_multipart_and_decodes_the_image(fake_server, config, scene_rgb):
    goal = np.full_like(scene_rgb, 200)
    fake_server.script(openai_image(goal))
    result = OpenAIEditor(config).edit(EditRequest(scene_rgb, "move the red block"))
    np.testing.assert_array_equal(result.rgb, goal)
    path, headers, body = fake_server.requests[0]
    assert path == "/v1/images/edits"
    assert headers["authorization"] == "Bearer sk-test"
    assert headers["content-type"].startswith("multipart/form-data")
    assert b"move the red block" in body and b"gpt-image-1" in body and b"\x89PNG" in body


def test_429_then_success_is_retried(fake_server, config, scene_rgb):
    fake_server.script(openai_error(429), openai_error(500), openai_image(scene_rgb))
    assert OpenAIEditor(config).edit(EditRequest(scene_rgb, "p")).rgb.shape == scene_rgb.shape
    assert len(fake_server.requests) == 3


def test_reply_without_image_is_a_recorded_failure(fake_server, config, scene_rgb):
    fake_server.script(json_reply({"created": 1, "data": []}))
    with pytest.raises(ProviderError) as e:
        OpenAIEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "no_image" and "0 image(s)" in e.value.raw


def test_malformed_body_is_a_clear_failure(fake_server, config, scene_rgb):
    fake_server.script(Reply(200, b"<html>oops</html>", content_type="text/html"), Reply(200, b"{not json"))
    editor = OpenAIEditor(config)
    for _ in range(2):
        with pytest.raises(ProviderError) as e:
            editor.edit(EditRequest(scene_rgb, "p"))
        assert e.value.kind == "malformed"


def test_timeout(fake_server, config, scene_rgb):
    fake_server.script(Reply(200, b"{}", delay_s=3.0))
    with pytest.raises(ProviderError) as e:
        OpenAIEditor(config).edit(EditRequest(scene_rgb, "p"))
    assert e.value.kind == "timeout"


def _reflection(rgb):
    mask = np.zeros(rgb.shape[:2], bool)
    mask[5:10, 5:10] = True
    return ReflectionRequest("put the red block on the plate", "prompt", rgb, rgb, rgb, mask, mask, "red block")


def test_reflect_requests_a_strict_json_schema(fake_server, config, scene_rgb):
    fake_server.script(openai_chat(json.dumps({"valid": True, "reasons": ["on the plate"], "revised_prompt": ""})))
    v = OpenAIVLM(config).reflect(_reflection(scene_rgb))
    assert v.valid and v.reasons == ("on the plate",) and v.revised_prompt is None
    path, _, body = fake_server.requests[0]
    sent = json.loads(body)
    assert path == "/v1/chat/completions"
    assert sent["response_format"]["type"] == "json_schema" and sent["response_format"]["json_schema"]["strict"]
    assert sent["messages"][0]["content"][1]["image_url"]["url"].startswith("data:image/png;base64,")


def test_refusal_and_malformed_verdicts_are_failures(fake_server, config, scene_rgb):
    fake_server.script(openai_chat(None, refusal="I can't help with that."), openai_chat("yes it is valid"))
    vlm = OpenAIVLM(config)
    with pytest.raises(ProviderError) as e:
        vlm.reflect(_reflection(scene_rgb))
    assert e.value.kind == "refused" and "can't help" in e.value.raw
    with pytest.raises(ProviderError) as e:
        vlm.reflect(_reflection(scene_rgb))
    assert e.value.kind == "malformed" and e.value.raw == "yes it is valid"


def test_missing_key_fails_at_construction(monkeypatch):
    monkeypatch.delenv("NO_SUCH_OPENAI_KEY", raising=False)
    with pytest.raises(MissingApiKeyError, match="NO_SUCH_OPENAI_KEY"):
        OpenAIVLM(OpenAIConfig(api_key_env="NO_SUCH_OPENAI_KEY"))
