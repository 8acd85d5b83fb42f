"""Gemini backends through google-genai: image editing (gemini-2.5-flash-image) and the text VLM (gemini-2.5-pro).

The SDK client gets the configured timeout and no retries of its own; retries with backoff on 429/5xx, and the
mapping of every other outcome to a ProviderError, happen here so each is visible and recorded.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.config import GeminiConfig
from pipeline.reasoning import prompts
from pipeline.reasoning.interfaces import ImageEditor, TextVLM
from pipeline.reasoning.prompts import reflect_with
from pipeline.reasoning.providers import (
    ProviderError,
    api_key,
    decode_image,
    kind_of_status,
    png_bytes,
    with_retries,
)
from pipeline.reasoning.types import EditRequest, EditResult, Enhancement, ReflectionRequest, Verdict

REFUSAL_REASONS = ("SAFETY", "PROHIBITED", "BLOCKLIST", "SPII", "RECITATION")
ASPECT_RATIOS = ("1:1", "2:3", "3:2", "3:4", "4:3", "4:5", "5:4", "9:16", "16:9", "21:9")


def nearest_aspect_ratio(width: int, height: int) -> str:
    """The supported output aspect ratio closest to the input's: the editor then has less reason to reframe."""
    return min(
        ASPECT_RATIOS, key=lambda r: abs(np.log(width / height) - np.log(int(r.split(":")[0]) / int(r.split(":")[1])))
    )


class _GeminiClient:
    def __init__(self, config: GeminiConfig) -> None:
        from google import genai
        from google.genai import types

        self.config = config
        self.types = types
        options = types.HttpOptions(base_url=config.base_url, timeout=int(config.timeout_s * 1000))
        key = api_key(config.api_key_env, "pipeline.gemini.api_key_env")
        self.client = genai.Client(api_key=key, http_options=options)

    def generate(self, model: str, contents: list, config: Any, what: str) -> Any:
        """One generate_content call with retries; SDK and transport errors become ProviderErrors."""
        c = self.config
        return with_retries(
            lambda: self._once(model, contents, config, what), what, c.max_attempts, c.backoff_s, c.backoff_max_s
        )

    def _once(self, model: str, contents: list, config: Any, what: str) -> Any:
        import httpx2
        from google.genai import errors

        try:
            return self.client.models.generate_content(model=model, contents=contents, config=config)
        except errors.APIError as e:
            raise ProviderError(kind_of_status(e.code), f"{what}: HTTP {e.code} {e.message}", str(e), e.code) from None
        except httpx2.TimeoutException:
            raise ProviderError("timeout", f"{what}: no reply within {self.config.timeout_s:g} s") from None
        except httpx2.TransportError as e:
            raise ProviderError("server", f"{what}: transport error ({e})") from None
        except ValueError as e:  # the SDK could not parse the reply body
            raise ProviderError("malformed", f"{what}: unreadable reply ({e})", str(e)) from None

    def image_part(self, rgb: np.ndarray) -> Any:
        return self.types.Part.from_bytes(data=png_bytes(rgb), mime_type="image/png")


def _parts(response: Any, what: str) -> tuple[list[Any], str]:
    """Parts of the first candidate and a record of the reply; a blocked prompt or safety stop is a refusal."""
    feedback = getattr(response, "prompt_feedback", None)
    block = getattr(feedback, "block_reason", None) if feedback else None
    candidates = response.candidates or []
    if not candidates:
        raise ProviderError("refused", f"{what}: no candidate (block reason {block})", raw=str(block))
    cand = candidates[0]
    finish = str(getattr(cand, "finish_reason", "") or "")
    parts = list(cand.content.parts or []) if cand.content else []
    texts = " ".join(p.text for p in parts if getattr(p, "text", None))
    raw = f"finish_reason={finish} text={texts!r}"
    if not parts and any(r in finish for r in REFUSAL_REASONS):
        raise ProviderError("refused", f"{what}: stopped for {finish}", raw=raw)
    return parts, raw


class GeminiEditor(ImageEditor):
    name = "gemini"

    def __init__(self, config: GeminiConfig) -> None:
        self.api = _GeminiClient(config)
        self.config = config

    def edit(self, request: EditRequest) -> EditResult:
        what = f"gemini edit ({self.config.image_model})"
        types = self.api.types
        aspect = nearest_aspect_ratio(request.rgb.shape[1], request.rgb.shape[0])
        cfg = types.GenerateContentConfig(
            response_modalities=["IMAGE", "TEXT"], image_config=types.ImageConfig(aspect_ratio=aspect)
        )
        contents = [request.prompt, self.api.image_part(request.rgb)]
        response = self.api.generate(self.config.image_model, contents, cfg, what)
        parts, raw = _parts(response, what)
        images = [p.inline_data for p in parts if getattr(p, "inline_data", None) and p.inline_data.data]
        if not images:
            finish = raw.split(" ")[0]
            kind = "refused" if any(r in finish for r in REFUSAL_REASONS) else "no_image"
            raise ProviderError(kind, f"{what}: reply has no image part ({raw})", raw=raw)
        return EditResult(decode_image(images[0].data, what), raw=raw)


class GeminiVLM(TextVLM):
    name = "gemini"

    def __init__(self, config: GeminiConfig) -> None:
        self.api = _GeminiClient(config)
        self.config = config

    def _json(self, text: str, rgb: np.ndarray, schema: dict, what: str) -> str:
        cfg = self.api.types.GenerateContentConfig(response_mime_type="application/json", response_json_schema=schema)
        response = self.api.generate(self.config.text_model, [text, self.api.image_part(rgb)], cfg, what)
        parts, raw = _parts(response, what)
        text = "".join(p.text for p in parts if getattr(p, "text", None))
        if not text:
            raise ProviderError("malformed", f"{what}: reply has no text ({raw})", raw=raw)
        return text

    def enhance(self, rgb: np.ndarray, instruction: str) -> Enhancement:
        return prompts.enhance_with(self._json, rgb, instruction, f"gemini enhance ({self.config.text_model})")

    def reflect(self, request: ReflectionRequest) -> Verdict:
        return reflect_with(self._json, request, f"gemini reflect ({self.config.text_model})")
