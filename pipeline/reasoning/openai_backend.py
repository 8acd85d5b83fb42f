"""OpenAI backends through openai: image edits (gpt-image-1) and a vision chat model with JSON-schema output.

The SDK client gets the configured timeout and max_retries=0; retries with backoff on 429/5xx and the mapping of
every other outcome to a ProviderError happen here, as for Gemini.
"""

from __future__ import annotations

import base64
import binascii
from typing import Any

import numpy as np

from pipeline.config import OpenAIConfig
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


class _OpenAIClient:
    def __init__(self, config: OpenAIConfig) -> None:
        import openai

        self.config = config
        key = api_key(config.api_key_env, "pipeline.openai.api_key_env")
        self.client = openai.OpenAI(api_key=key, base_url=config.base_url, timeout=config.timeout_s, max_retries=0)

    def call(self, fn, what: str, **kwargs: Any) -> Any:
        c = self.config
        return with_retries(lambda: self._once(fn, what, kwargs), what, c.max_attempts, c.backoff_s, c.backoff_max_s)

    def _once(self, fn, what: str, kwargs: dict) -> Any:
        import openai

        try:
            return fn(**kwargs)
        except openai.APITimeoutError:
            raise ProviderError("timeout", f"{what}: no reply within {self.config.timeout_s:g} s") from None
        except openai.APIStatusError as e:
            raise ProviderError(
                kind_of_status(e.status_code), f"{what}: HTTP {e.status_code} {e.message}", str(e.body), e.status_code
            ) from None
        except openai.APIConnectionError as e:
            raise ProviderError("server", f"{what}: connection failed ({e})") from None
        except (ValueError, openai.APIResponseValidationError) as e:
            raise ProviderError("malformed", f"{what}: unreadable reply ({e})", str(e)) from None


class OpenAIEditor(ImageEditor):
    name = "openai"

    def __init__(self, config: OpenAIConfig) -> None:
        self.api = _OpenAIClient(config)
        self.config = config

    def edit(self, request: EditRequest) -> EditResult:
        what = f"openai edit ({self.config.image_model})"
        image = ("initial.png", png_bytes(request.rgb), "image/png")
        images = self.api.client.images
        reply = self.api.call(images.edit, what, model=self.config.image_model, image=image, prompt=request.prompt)
        if not hasattr(reply, "data"):  # the SDK hands back non-JSON bodies as they are
            raise ProviderError("malformed", f"{what}: reply is not an image response", raw=str(reply)[:2000])
        data = list(reply.data or [])
        b64 = getattr(data[0], "b64_json", None) if data else None
        raw = f"{len(data)} image(s); revised_prompt={getattr(data[0], 'revised_prompt', None) if data else None!r}"
        if not b64:
            raise ProviderError("no_image", f"{what}: reply has no base64 image ({raw})", raw=raw)
        try:
            png = base64.b64decode(b64, validate=True)
        except (binascii.Error, ValueError):
            raise ProviderError("malformed", f"{what}: image is not valid base64", raw=raw) from None
        return EditResult(decode_image(png, what), raw=raw)


class OpenAIVLM(TextVLM):
    name = "openai"

    def __init__(self, config: OpenAIConfig) -> None:
        self.api = _OpenAIClient(config)
        self.config = config

    def _json(self, text: str, rgb: np.ndarray, schema: dict, what: str) -> str:
        url = "data:image/png;base64," + base64.b64encode(png_bytes(rgb)).decode()
        messages = [
            {
                "role": "user",
                "content": [{"type": "text", "text": text}, {"type": "image_url", "image_url": {"url": url}}],
            }
        ]
        fmt = {"type": "json_schema", "json_schema": {"name": "reply", "schema": schema, "strict": True}}
        completions = self.api.client.chat.completions
        reply = self.api.call(
            completions.create, what, model=self.config.text_model, messages=messages, response_format=fmt
        )
        if not reply.choices:
            raise ProviderError("malformed", f"{what}: reply has no choices")
        message = reply.choices[0].message
        if getattr(message, "refusal", None):
            raise ProviderError("refused", f"{what}: {message.refusal}", raw=message.refusal)
        if not message.content:
            raise ProviderError("malformed", f"{what}: empty message (finish {reply.choices[0].finish_reason})")
        return message.content

    def enhance(self, rgb: np.ndarray, instruction: str) -> Enhancement:
        return prompts.enhance_with(self._json, rgb, instruction, f"openai enhance ({self.config.text_model})")

    def reflect(self, request: ReflectionRequest) -> Verdict:
        return reflect_with(self._json, request, f"openai reflect ({self.config.text_model})")
