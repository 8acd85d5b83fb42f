"""Prompts and reply handling for the cloud text VLMs (enhancement, reflection), shared by Gemini and OpenAI."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pipeline.reasoning.providers import EnhancementReply, VerdictReply, json_schema, parse_reply
from pipeline.reasoning.types import Enhancement, ReflectionRequest, Verdict

ENHANCE = """You prepare an image-editing request for a robot. The image shows a table-top scene seen by the robot's
fixed camera. The operator's instruction is:

    {instruction}

Write `edit_prompt`: one precise instruction for an image-editing model that shows the scene AFTER the instruction
is carried out. Name the object that moves by its colour, shape and position, say exactly where and how it ends up
(position relative to other named objects, orientation, resting on which surface), and require that the camera
viewpoint, zoom, framing, lighting, background, the robot and every other object stay exactly as in the input
image, that the moved object keeps its size, shape and colour, and that it appears exactly once.
Write `target_object`: a short noun phrase (two to four words, e.g. "red block") naming the object that moves,
suitable for an open-vocabulary detector. Write `reference_object`: the same for the object it is placed relative
to, or an empty string if there is none. When only a part of an object moves (a lid that closes, a door that
opens), `target_object` names that part (e.g. "lid of the blue box") and `anchor_object` the object it belongs to
(e.g. "blue box"), which stays where it is; otherwise `anchor_object` is an empty string. When the instruction
moves several like objects together (sweep the screws into the dustpan), `target_object` names them in the plural
(e.g. "yellow screws"), `several_targets` is true, the edit shows every one of them moved, and `reference_object`
names where they go; otherwise `several_targets` is false. When the robot must use a tool to move them (a
sweep is done with a brush unless the instruction names another tool), `tool_object` names the tool (e.g. "blue
brush") and the edit shows the tool exactly where it is now; otherwise `tool_object` is an empty string. Lifting
or picking up an object shows it raised straight up, held in the air, the stated height or 10 cm; taking an
object off or out of its support shows it standing on the table next to the support, which is left empty.
Answer with JSON only."""

REFLECT = """You check a candidate goal for a robot. The operator's instruction is:

    {instruction}

The image-editing model was asked: {prompt}

The image shows the ORIGINAL scene with the edited result of the moved object ({target}) blended in
semi-transparently where the editor put it (several like objects, when the target names several: all of them).
Decide whether the blended object's position and orientation carry out the instruction physically plausibly: it
rests on a support (or, lifted, is held straight above where it was), does not intersect other objects, has its
original size and appearance, and stands in the requested relation to the other objects (swept parts: every one
of them inside the container).
Answer with JSON only: `valid` (true or false), `reasons` (short sentences, what is right or wrong) and
`revised_prompt` (when invalid: a corrected editing prompt that fixes what was wrong; when valid: an empty string)."""


def reflect_with(ask: Callable[[str, np.ndarray, dict, str], str], request: ReflectionRequest, what: str) -> Verdict:
    """Reflection through any JSON-answering VLM call: prompt, overlay image, strict verdict schema."""
    text = REFLECT.format(instruction=request.instruction, prompt=request.prompt, target=request.target)
    raw = ask(text, request.overlay, json_schema(VerdictReply), what)
    reply = parse_reply(raw, VerdictReply, what)
    revised = reply.revised_prompt.strip() or None
    return Verdict(reply.valid, tuple(reply.reasons), None if reply.valid else revised, raw=raw)


def enhance_with(
    ask: Callable[[str, np.ndarray, dict, str], str], rgb: np.ndarray, instruction: str, what: str
) -> Enhancement:
    """Prompt enhancement through any JSON-answering VLM call, with the strict enhancement schema."""
    raw = ask(ENHANCE.format(instruction=instruction), rgb, json_schema(EnhancementReply), what)
    reply = parse_reply(raw, EnhancementReply, what)
    optional = lambda text: text.strip() or None  # noqa: E731
    return Enhancement(
        reply.edit_prompt,
        reply.target_object,
        optional(reply.reference_object),
        raw,
        optional(reply.anchor_object),
        tool=optional(reply.tool_object),
        group=reply.several_targets,
    )
