"""Provider robustness shared by the cloud backends: typed failures, retries with backoff, API keys, images.

Every call has a timeout (set on the SDK client); HTTP 429 and 5xx are retried with exponential backoff up to
`max_attempts`; anything else (no image, malformed JSON, refusal, 4xx, timeout) fails at once as a
ProviderError whose `kind` and `raw` go into the run record.
"""

from __future__ import annotations

import io
import json
import logging
import os
import time
from collections.abc import Callable
from typing import Literal, TypeVar

import numpy as np
from PIL import Image
from pydantic import BaseModel, ConfigDict, ValidationError

log = logging.getLogger(__name__)
T = TypeVar("T")
FailureKind = Literal["timeout", "rate_limited", "server", "client", "auth", "no_image", "malformed", "refused"]


class ProviderError(RuntimeError):
    """A provider call produced nothing usable. `retryable` marks 429/5xx; `raw` is the reply text, if any."""

    def __init__(self, kind: FailureKind, message: str, raw: str = "", status: int | None = None) -> None:
        super().__init__(f"{kind}: {message}")
        self.kind = kind
        self.raw = raw
        self.status = status

    @property
    def retryable(self) -> bool:
        return self.kind in ("rate_limited", "server")

    @property
    def fatal(self) -> bool:
        """Failures no further iteration can fix (bad key, bad model name)."""
        return self.kind in ("auth", "client")


def kind_of_status(status: int) -> FailureKind:
    if status == 429:
        return "rate_limited"
    if status >= 500:
        return "server"
    if status in (401, 403):
        return "auth"
    return "client"


class MissingApiKeyError(RuntimeError):
    pass


def api_key(env_var: str, config_key: str) -> str:
    """The key from the environment, or a start-up error naming the variable and the config key that names it."""
    key = os.environ.get(env_var, "").strip()
    if not key:
        raise MissingApiKeyError(
            f"environment variable {env_var} is not set: it must hold the API key ({config_key} names the "
            "variable); set it, or choose the offline backends"
        )
    return key


def with_retries(
    call: Callable[[], T],
    what: str,
    max_attempts: int,
    backoff_s: float,
    backoff_max_s: float,
    sleep: Callable[[float], None] = time.sleep,
) -> T:
    """Run `call`, retrying retryable ProviderErrors with exponential backoff; the last error propagates."""
    for attempt in range(1, max_attempts + 1):
        try:
            return call()
        except ProviderError as e:
            if not e.retryable or attempt == max_attempts:
                raise
            wait = min(backoff_s * 2 ** (attempt - 1), backoff_max_s)
            log.warning("%s: %s (attempt %d/%d); retrying in %.1f s", what, e, attempt, max_attempts, wait)
            sleep(wait)
    raise AssertionError("unreachable")


def png_bytes(rgb: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


def decode_image(data: bytes, what: str) -> np.ndarray:
    """Image bytes -> (H, W, 3) uint8 RGB; a payload that is not an image is a 'malformed' failure."""
    try:
        with Image.open(io.BytesIO(data)) as im:
            return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
    except Exception as e:  # PIL raises several unrelated types for corrupt data
        raise ProviderError("malformed", f"{what}: image part could not be decoded ({e})") from None


class VerdictReply(BaseModel):
    """The JSON schema the reflector must answer with."""

    model_config = ConfigDict(extra="forbid")
    valid: bool
    reasons: list[str]
    revised_prompt: str


class EnhancementReply(BaseModel):
    model_config = ConfigDict(extra="forbid")
    edit_prompt: str
    target_object: str
    reference_object: str
    anchor_object: str
    # asked of every model (the schema requires them); a reply from before they existed still parses
    tool_object: str = ""
    several_targets: bool = False


def json_schema(model: type[BaseModel]) -> dict:
    """A strict JSON schema (every property required, no extras, no defaults), accepted by both providers."""
    schema = model.model_json_schema()
    schema.pop("title", None)
    for prop in schema["properties"].values():
        prop.pop("title", None)
        prop.pop("default", None)
    schema["required"] = list(schema["properties"])
    schema["additionalProperties"] = False
    return schema


M = TypeVar("M", bound=BaseModel)


def parse_reply(text: str | None, model: type[M], what: str) -> M:
    if not text:
        raise ProviderError("malformed", f"{what}: empty reply where JSON was required", raw=text or "")
    try:
        return model.model_validate(json.loads(text))
    except (json.JSONDecodeError, ValidationError) as e:
        raise ProviderError("malformed", f"{what}: reply does not match the schema ({e})", raw=text) from None
