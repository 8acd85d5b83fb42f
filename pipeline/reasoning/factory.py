"""Build stage 1 from the profile's pipeline section; every missing key or unusable setting fails here, at start-up."""

from __future__ import annotations

from drivers.optional import missing_package
from pipeline.config import PipelineConfig
from pipeline.perception.depth import DepthEstimator, OfflineDepthEstimator
from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.perception.segmenter import Segmenter
from pipeline.reasoning.interfaces import ImageEditor, TextVLM
from pipeline.reasoning.providers import MissingApiKeyError, api_key
from pipeline.reasoning.reasoner import Reasoner

MODEL_PACKAGES = (("torch", "torch"), ("transformers", "transformers"))
PACKAGES = {  # backend -> (import, distribution) it needs
    "gemini": (("google.genai", "google-genai"),),
    "openai": (("openai", "openai"),),
    "grounded_sam": MODEL_PACKAGES,
    "depth_anything": MODEL_PACKAGES,
    "dinov2": MODEL_PACKAGES,
}


def preflight(config: PipelineConfig) -> list[str]:
    """Problems that would stop the pipeline (missing API keys, missing packages of the backends the profile
    names), found without building anything."""
    return missing_api_keys(config) + missing_packages(config)


def missing_packages(config: PipelineConfig) -> list[str]:
    steps = (
        ("editor", config.editor),
        ("vlm", config.vlm),
        ("segmenter", config.segmenter),
        ("depth", config.depth),
        ("features", config.features),
    )
    problems = (
        missing_package(module, dist, f"pipeline.{step} = {backend}")
        for step, backend in steps
        for module, dist in PACKAGES.get(backend, ())
    )
    return [p for p in problems if p is not None]


def missing_api_keys(config: PipelineConfig) -> list[str]:
    problems = []
    for step, backend in (("editor", config.editor), ("vlm", config.vlm)):
        if backend in ("gemini", "openai"):
            provider = getattr(config, backend)
            try:
                api_key(provider.api_key_env, f"pipeline.{backend}.api_key_env")
            except MissingApiKeyError as e:
                problems.append(f"pipeline.{step} = {backend}: {e}")
    return problems


def build_segmenter(config: PipelineConfig) -> Segmenter:
    if config.segmenter == "grounded_sam":
        from pipeline.perception.grounded_sam import GroundedSamSegmenter

        return GroundedSamSegmenter(config.grounded_sam)
    return OfflineSegmenter()


def build_depth(config: PipelineConfig) -> DepthEstimator:
    if config.depth == "depth_anything":
        from pipeline.perception.depth_anything import DepthAnythingEstimator

        return DepthAnythingEstimator(config.depth_anything)
    return OfflineDepthEstimator()


def _editor(config: PipelineConfig, segmenter: Segmenter, depth: DepthEstimator) -> ImageEditor:
    if config.editor == "gemini":
        from pipeline.reasoning.gemini import GeminiEditor

        return GeminiEditor(config.gemini)
    if config.editor == "openai":
        from pipeline.reasoning.openai_backend import OpenAIEditor

        return OpenAIEditor(config.openai)
    from pipeline.reasoning.offline_editor import OfflineEditor

    return OfflineEditor(segmenter, depth if isinstance(depth, OfflineDepthEstimator) else None)


def _vlm(config: PipelineConfig, segmenter: Segmenter) -> TextVLM:
    if config.vlm == "gemini":
        from pipeline.reasoning.gemini import GeminiVLM

        return GeminiVLM(config.gemini)
    if config.vlm == "openai":
        from pipeline.reasoning.openai_backend import OpenAIVLM

        return OpenAIVLM(config.openai)
    from pipeline.reasoning.offline_vlm import OfflineVLM

    return OfflineVLM(segmenter)


def build_reasoner(config: PipelineConfig) -> Reasoner:
    """The configured Reasoner. Raises MissingApiKeyError (all missing keys named) before building anything."""
    problems = missing_api_keys(config)
    if problems:
        raise MissingApiKeyError("cannot start goal reasoning:\n  " + "\n  ".join(problems))
    segmenter = build_segmenter(config)
    depth = build_depth(config)
    return Reasoner(_editor(config, segmenter, depth), _vlm(config, segmenter), segmenter, depth, config)
