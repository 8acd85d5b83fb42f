"""Goal-VLA method settings: which backend serves each model-facing step, and each backend's settings.

Defaults are the offline backends, so the default profile needs no key, network or weights. Cloud backends
read their API key from the environment variable named here; `build_reasoner` checks it at start-up.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from drivers.config import StrictModel
from pipeline.contact.types import ContactConfig
from pipeline.grounding.types import GroundingConfig
from pipeline.perception.config import DepthAnythingConfig, Dinov2Config, GroundedSamConfig


class ProviderConfig(StrictModel):
    """Connection settings of a cloud provider; every call times out, 429/5xx are retried with backoff."""

    api_key_env: str = Field(pattern=r"^[A-Z_][A-Z0-9_]*$", description="environment variable holding the key")
    base_url: str | None = Field(default=None, description="override the API endpoint (proxies, tests)")
    timeout_s: float = Field(default=120.0, gt=0, le=600, description="per HTTP call")
    max_attempts: int = Field(default=3, ge=1, le=10, description="tries per call on HTTP 429 and 5xx")
    backoff_s: float = Field(default=2.0, ge=0, le=60, description="first wait between tries; doubles each retry")
    backoff_max_s: float = Field(default=30.0, ge=0, le=600)


class GeminiConfig(ProviderConfig):
    api_key_env: str = "GEMINI_API_KEY"
    image_model: str = "gemini-2.5-flash-image"
    text_model: str = "gemini-2.5-pro"


class OpenAIConfig(ProviderConfig):
    api_key_env: str = "OPENAI_API_KEY"
    image_model: str = "gpt-image-1"
    text_model: str = "gpt-4.1"


class ChecksConfig(StrictModel):
    """Cheap geometric checks run on every candidate before the reflector is asked."""

    framing: Literal["reregister", "refuse"] = Field(
        default="reregister", description="on a zoom/shift/aspect change: warp the candidate back, or refuse it"
    )
    max_shift_px: float = Field(default=2.0, ge=0, description="framing counts as changed beyond this shift")
    max_scale_change: float = Field(default=0.01, ge=0, description="... or beyond this relative zoom")
    max_reregister_scale_change: float = Field(default=0.25, gt=0, le=1, description="refuse larger zooms outright")
    pixel_change_threshold: int = Field(default=40, ge=1, le=255, description="background colour change per pixel")
    max_changed_blob_frac: float = Field(
        default=0.0015,
        gt=0,
        le=1,
        description="a changed background region larger than this image fraction = moved object",
    )
    max_target_iou: float = Field(default=0.97, gt=0, le=1, description="target mask overlap meaning 'did not move'")
    mask_margin_px: int = Field(
        default=6, ge=0, le=200, description="masks are grown by this much when comparing backgrounds"
    )


class PipelineConfig(StrictModel):
    editor: Literal["offline", "gemini", "openai"] = "offline"
    vlm: Literal["offline", "gemini", "openai"] = "offline"
    segmenter: Literal["offline", "grounded_sam"] = "offline"
    depth: Literal["offline", "depth_anything"] = "offline"
    features: Literal["offline", "dinov2"] = "offline"
    reflection_iterations: int = Field(default=3, ge=1, le=10)
    overlay_alpha: float = Field(default=0.5, gt=0, le=1, description="goal object opacity in the synthesis overlay")
    allow_unvalidated_goal: bool = Field(
        default=False, description="operator override: use the last candidate when none validates (never default)"
    )
    gemini: GeminiConfig = GeminiConfig()
    openai: OpenAIConfig = OpenAIConfig()
    grounded_sam: GroundedSamConfig = GroundedSamConfig()
    depth_anything: DepthAnythingConfig = DepthAnythingConfig()
    dinov2: Dinov2Config = Dinov2Config()
    grounding: GroundingConfig = GroundingConfig()
    contact: ContactConfig = ContactConfig()
    checks: ChecksConfig = ChecksConfig()
