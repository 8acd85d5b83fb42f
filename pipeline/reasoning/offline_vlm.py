"""Offline text VLM: enhancement = parsing into the grammar; reflection = checking the relation in the goal image.

The enhancer rewrites the instruction canonically (the offline editor reads the same grammar) and names the
target and reference phrases. The reflector segments the reference object where it stands (in the initial image:
it does not move, and the goal object set on it or in front of it would change its outline in the candidate) and
checks, in image space, that the segmented goal object stands in the requested relation to it; motions without a
reference
(rotate, push, stand up) pass when the geometric checks already saw the target change.
"""

from __future__ import annotations

import cv2
import numpy as np

from pipeline.perception.offline_segmenter import COLOUR_WORDS, parse_phrase
from pipeline.perception.segmenter import Detection, SegmentationError, Segmenter, apart_from, matches
from pipeline.reasoning.instruction import InstructionError, lid_of, parse_instruction
from pipeline.reasoning.interfaces import TextVLM
from pipeline.reasoning.providers import ProviderError
from pipeline.reasoning.types import Enhancement, ReflectionRequest, Verdict

COLOUR_NAMES = frozenset(COLOUR_WORDS.values())


class OfflineVLM(TextVLM):
    name = "offline"

    def __init__(self, segmenter: Segmenter) -> None:
        self.segmenter = segmenter

    def enhance(self, rgb: np.ndarray, instruction: str) -> Enhancement:
        try:
            instr = parse_instruction(instruction)
        except InstructionError as e:
            raise ProviderError("refused", str(e), raw=str(e)) from None
        prompt = instr.canonical()
        if instr.action == "close":  # only the lid moves; the box it is hinged to stays
            return Enhancement(prompt, lid_of(instr.target), raw=prompt, anchor=instr.target)
        if instr.action == "sweep":  # every instance the phrase names, moved with the tool
            target = self._with_colour(rgb, instr.target)
            prompt = instr.canonical().replace(f"the {instr.target} ", f"the {target} ", 1)
            return Enhancement(prompt, target, instr.reference, raw=prompt, tool=instr.tool, group=True)
        return Enhancement(prompt, instr.target, instr.reference, raw=prompt)

    def _with_colour(self, rgb: np.ndarray, phrase: str) -> str:
        """A group named by shape alone ("the screws") named by its colour too when all its instances share one,
        as a person looking at the scene would: small parts that end up touching are then still found by colour."""
        if parse_phrase(phrase).colour is not None:
            return phrase
        try:
            found = self.segmenter.segment(rgb, phrase)
        except SegmentationError:
            return phrase
        colours = {d.label.split()[0] for d in found}
        return f"{colours.pop()} {phrase}" if len(colours) == 1 and next(iter(colours), "") in COLOUR_NAMES else phrase

    def correct(self, prompt: str, problems: list[str]) -> str:
        return prompt  # the offline editor is deterministic: rewording cannot help, and it must stay in the grammar

    def reflect(self, request: ReflectionRequest) -> Verdict:
        instr = parse_instruction(request.prompt)
        if instr.action == "sweep":
            return self._reflect_sweep(request, instr)
        if instr.action != "place":
            return Verdict(True, (f"{instr.target} changed as asked ({instr.action}); no relation to check",))
        try:
            found = apart_from(
                self.segmenter.segment(request.rgb_init, instr.reference, request.depth_init), request.mask_init
            )
        except SegmentationError as e:
            return Verdict(False, (f"reference '{instr.reference}' not segmentable: {e}",))
        if len(found) != 1:
            reason = f"reference '{instr.reference}' {matches(found)} in the initial image (needs exactly one)"
            return Verdict(False, (reason,))
        ok, reason = relation_holds(request.mask_goal, found[0], instr.relation, instr.target, instr.reference)
        return Verdict(ok, (reason,), None if ok else request.prompt, raw=reason)

    def _reflect_sweep(self, request: ReflectionRequest, instr) -> Verdict:
        """Every part of the swept group in the goal image lies within the container's outline in the initial one."""
        try:
            found = self.segmenter.segment(request.rgb_init, instr.reference, request.depth_init)
        except SegmentationError as e:
            return Verdict(False, (f"container '{instr.reference}' not segmentable: {e}",))
        if len(found) != 1:
            return Verdict(False, (f"container '{instr.reference}' {matches(found)} in the initial image",))
        ok, reason = group_inside(request.mask_goal, found[0], instr.target, instr.reference)
        return Verdict(ok, (reason,), None if ok else request.prompt, raw=reason)


def group_inside(mask: np.ndarray, container: Detection, target: str, reference: str) -> tuple[bool, str]:
    """Image-space test that each part of a group (a connected piece of its mask) lies in the container's box."""
    n, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    u0, v0, u1, v1 = container.box
    outside = []
    for k in range(1, n):
        v, u = np.nonzero(labels == k)
        if not (u0 <= u.mean() <= u1 and v0 <= v.mean() <= v1 + 3):
            outside.append(f"({u.mean():.0f}, {v.mean():.0f})")
    where = f"{reference} box u {u0}..{u1}, v {v0}..{v1}"
    if outside:
        return (
            False,
            f"{len(outside)} of {n - 1} parts of the {target} lie outside the {reference}: "
            f"{', '.join(outside)}; {where}",
        )
    return True, f"all {n - 1} parts of the {target} lie in the {reference} ({where})"


def relation_holds(mask: np.ndarray, ref: Detection, relation: str, target: str, reference: str) -> tuple[bool, str]:
    """Image-space test of a spatial relation between the goal object mask and the reference detection."""
    v, u = np.nonzero(mask)
    uc, bottom = float(u.mean()), float(np.percentile(v, 95))
    u0, v0, u1, v1 = ref.box
    ruc, rvc = ref.centroid_uv
    where = f"{target} centre u={uc:.0f}, bottom v={bottom:.0f}; {reference} box u {u0}..{u1}, v {v0}..{v1}"
    if relation in ("on", "in"):
        ok = u0 <= uc <= u1 and v0 <= bottom <= v1 + 3
    elif relation == "left_of":
        ok = uc < u0
    elif relation == "right_of":
        ok = uc > u1
    elif relation == "behind":
        ok = bottom < rvc
    elif relation == "in_front_of":
        ok = bottom > v1
    else:  # next to: apart (or in front of it, hiding part of it), and no farther than two object sizes
        overlap = (mask & ref.mask).any() and bottom <= v1
        gap = max(abs(uc - ruc) - (u1 - u0) / 2 - np.ptp(u) / 2, abs(float(v.mean()) - rvc) - (v1 - v0) / 2, 0.0)
        ok = bool(not overlap and gap < 2.0 * max(u1 - u0, v1 - v0, np.ptp(u)))
    verb = "holds" if ok else "does not hold"
    return ok, f"'{relation.replace('_', ' ')}' {verb}: {where}"
