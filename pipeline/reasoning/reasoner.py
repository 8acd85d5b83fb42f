"""Stage 1 of Goal-VLA: prompt enhancement, then Reflection-through-Synthesis until a goal is validated.

Each iteration: edit the initial image with the current prompt; bring the candidate to the initial resolution;
segment the target in it; run the cheap geometric checks (framing, missing/duplicated target, other objects
moved, target unchanged), re-registering a changed framing when allowed; overlay the segmented goal object at
`overlay_alpha` on the initial image (the synthesis); ask the reflector for a structured verdict. Checks that
fail stand in for the verdict (no reflector call). If no candidate validates the run fails with every reason;
only the operator's explicit `allow_unvalidated` override lets the last usable candidate through.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from drivers.types import RGBDFrame
from pipeline.config import PipelineConfig
from pipeline.perception.depth import DepthEstimationError, DepthEstimator
from pipeline.perception.segmenter import Detection, SegmentationError, Segmenter, attached_to, grow, matches
from pipeline.reasoning import checks, group
from pipeline.reasoning.instruction import with_colour_found
from pipeline.reasoning.interfaces import ImageEditor, TextVLM
from pipeline.reasoning.providers import ProviderError
from pipeline.reasoning.record import Recorder
from pipeline.reasoning.types import (
    EditRequest,
    EditResult,
    GoalState,
    Iteration,
    ReasoningError,
    ReflectionRequest,
    Verdict,
)

log = logging.getLogger(__name__)


def synthesize(rgb_init: np.ndarray, rgb_goal: np.ndarray, mask_goal: np.ndarray, alpha: float) -> np.ndarray:
    """The 'virtual image': the goal object blended at opacity `alpha` into the initial scene."""
    out = rgb_init.astype(np.float32)
    out[mask_goal] = alpha * rgb_goal[mask_goal].astype(np.float32) + (1.0 - alpha) * out[mask_goal]
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


@dataclass
class _Candidate:
    rgb: np.ndarray
    mask: np.ndarray
    result: EditResult
    iteration: Iteration


class Reasoner:
    def __init__(
        self,
        editor: ImageEditor,
        vlm: TextVLM,
        segmenter: Segmenter,
        depth: DepthEstimator,
        config: PipelineConfig | None = None,
    ) -> None:
        self.editor, self.vlm, self.segmenter, self.depth = editor, vlm, segmenter, depth
        self.config = config or PipelineConfig()

    def run(
        self,
        frame: RGBDFrame,
        instruction: str,
        record_dir: str | None = None,
        allow_unvalidated: bool | None = None,
    ) -> GoalState:
        cfg = self.config
        allow = cfg.allow_unvalidated_goal if allow_unvalidated is None else allow_unvalidated
        rec = Recorder(record_dir)
        rgb = frame.rgb
        seconds: dict[str, float] = {}
        rec.image("initial.png", rgb)
        rec.text("instruction.txt", instruction)

        t0 = time.perf_counter()
        try:
            enh = self.vlm.enhance(rgb, instruction)
        except ProviderError as e:
            rec.json("enhancement_failure.json", {"kind": e.kind, "error": str(e), "raw": e.raw})
            raise ReasoningError(f"prompt enhancement failed: {e}", [str(e)]) from e
        seconds["enhance"] = time.perf_counter() - t0
        rec.json(
            "enhancement.json",
            {
                "prompt": enh.prompt,
                "target": enh.target,
                "reference": enh.reference,
                "anchor": enh.anchor,
                "tool": enh.tool,
                "group": enh.group,
            },
        )
        rec.text("enhancement_raw.txt", enh.raw)

        t0 = time.perf_counter()
        initial = self._segment(rgb, enh.target, frame.depth)
        seconds["segment"] = time.perf_counter() - t0
        if enh.group:
            mask_init = group.initial_union(initial, enh.target)
        elif len(initial) != 1:
            reason = f"target '{enh.target}' {matches(initial)} in the initial image (needs exactly one)"
            raise ReasoningError(reason, [reason])
        else:
            mask_init = initial[0].mask
        rec.image("mask_init.png", mask_init)
        mask_tool = mask_reference = None
        if enh.tool or enh.group:  # a sweep: the tool it is done with and the container it goes into
            mask_tool = self._single(frame, enh.tool, "tool") & ~mask_init if enh.tool else None
            mask_reference = self._single(frame, enh.reference, "reference") & ~mask_init if enh.reference else None
            for name, mask in (("mask_tool.png", mask_tool), ("mask_reference.png", mask_reference)):
                if mask is not None:
                    rec.image(name, mask)
        enh = replace(enh, target=with_colour_found(enh.target, initial[0].label))  # to find it again, moved
        mask_anchor = None
        if enh.anchor:
            anchors = attached_to(self._segment(rgb, enh.anchor, frame.depth), mask_init)
            if len(anchors) != 1:
                reason = f"anchor '{enh.anchor}' {matches(anchors)} in the initial image (needs exactly one)"
                raise ReasoningError(reason, [reason])
            mask_anchor = anchors[0].mask & ~mask_init
            rec.image("mask_anchor.png", mask_anchor)

        prompt, accepted, usable = enh.prompt, None, None
        iterations: list[Iteration] = []
        for index in range(1, cfg.reflection_iterations + 1):
            it = Iteration(index, prompt)
            iterations.append(it)
            group_size = len(initial) if enh.group else None
            candidate = self._iterate(frame, instruction, enh, mask_init, it, rec, seconds, group_size, mask_anchor)
            rec.json("iteration.json", it, index)
            if candidate is not None:
                usable = candidate
                if it.verdict is not None and it.verdict.valid:
                    accepted = candidate
                    break
            if it.verdict is not None and it.verdict.revised_prompt:
                prompt = it.verdict.revised_prompt
            if it.failure_kind in ("auth", "client"):
                break  # no later iteration can fix a bad key or model name

        reasons = _by_iterations(iterations)
        if accepted is None:
            if not (allow and usable is not None):
                rec.json("reasoning.json", {"ok": False, "reasons": reasons, "seconds": seconds})
                raise ReasoningError(
                    f"no validated goal after {len(iterations)} iteration(s):\n  " + "\n  ".join(reasons), reasons
                )
            log.warning("operator override: using an unvalidated goal (iteration %d)", usable.iteration.index)
            accepted = usable

        t0 = time.perf_counter()
        depth_goal = accepted.result.relative_depth
        if depth_goal is None or accepted.iteration.registered:
            try:
                depth_goal = self.depth.estimate(accepted.rgb)
            except DepthEstimationError as e:
                raise ReasoningError(f"goal depth: {e}", [str(e)]) from e
        seconds["depth"] = time.perf_counter() - t0

        goal = GoalState(
            instruction=instruction,
            prompt=accepted.iteration.prompt,
            target=enh.target,
            rgb_init=rgb,
            rgb_goal=accepted.rgb,
            mask_init=mask_init,
            mask_goal=accepted.mask,
            depth_goal=depth_goal,
            iterations=tuple(iterations),
            validated=accepted.iteration.verdict is not None and accepted.iteration.verdict.valid,
            T_goal_init_camera=accepted.result.T_goal_init_camera,
            seconds=seconds,
            mask_anchor=mask_anchor,
            group_size=len(initial) if enh.group else None,
            tool=enh.tool,
            mask_tool=mask_tool,
            reference=enh.reference if mask_reference is not None else None,
            mask_reference=mask_reference,
        )
        rec.image("goal.png", goal.rgb_goal)
        rec.image("mask_goal.png", goal.mask_goal)
        rec.array("goal_depth.npy", depth_goal.values)
        rec.json(
            "reasoning.json",
            {
                "ok": True,
                "validated": goal.validated,
                "override": not goal.validated,
                "accepted_iteration": accepted.iteration.index,
                "prompt": goal.prompt,
                "target": goal.target,
                "depth_kind": depth_goal.kind,
                "reasons": reasons,
                "seconds": seconds,
            },
        )
        return goal

    def _single(self, frame: RGBDFrame, phrase: str, role: str) -> np.ndarray:
        """The one instance `phrase` names in the initial image (a sweep's tool or container), else ReasoningError."""
        found = self._segment(frame.rgb, phrase, frame.depth)
        if len(found) != 1:
            reason = f"{role} '{phrase}' {matches(found)} in the initial image (needs exactly one)"
            raise ReasoningError(reason, [reason])
        return found[0].mask

    def _find_target(
        self, rgb, cand, enh, mask_init: np.ndarray, mask_anchor: np.ndarray | None, it: Iteration
    ) -> list[Detection]:
        """The target phrase's regions in the candidate; when there is none, found as checks.find_again finds them
        (a group's parts by their phrase alone)."""
        if enh.group:
            return self._segment(cand, enh.target)
        try:
            found, how = checks.find_again(self.segmenter, cand, enh.target, rgb, mask_init, mask_anchor=mask_anchor)
        except SegmentationError as e:
            raise ReasoningError(f"segmentation of '{enh.target}' failed: {e}", [str(e)]) from e
        if how:
            it.checks.append(f"target '{enh.target}' found only {how}")
        return found

    def _segment(self, rgb: np.ndarray, phrase: str, depth_m: np.ndarray | None = None) -> list[Detection]:
        try:
            return self.segmenter.segment(rgb, phrase, depth_m)
        except SegmentationError as e:
            raise ReasoningError(f"segmentation of '{phrase}' failed: {e}", [str(e)]) from e

    def _iterate(
        self,
        frame,
        instruction,
        enh,
        mask_init,
        it: Iteration,
        rec: Recorder,
        seconds,
        group_size: int | None = None,
        mask_anchor: np.ndarray | None = None,
    ) -> _Candidate | None:
        """One generate -> check -> synthesize -> reflect pass; fills `it`, returns a usable candidate or None.
        group_size: a group target's instances in the initial image (None: one object); mask_anchor: a part's
        object (a lid's box)."""
        cfg, rgb, i = self.config.checks, frame.rgb, it.index
        rec.text("prompt.txt", it.prompt, i)

        def lap(stage: str, t0: float) -> None:
            it.seconds[stage] = it.seconds.get(stage, 0.0) + time.perf_counter() - t0
            seconds[stage] = seconds.get(stage, 0.0) + time.perf_counter() - t0

        t0 = time.perf_counter()
        try:
            result = self.editor.edit(EditRequest(rgb, it.prompt, frame.depth, frame.intrinsics, frame.T_base_camera))
        except ProviderError as e:
            lap("edit", t0)
            it.failure, it.failure_kind = str(e), e.kind
            rec.text("edit_raw.txt", e.raw, i)
            return None
        lap("edit", t0)
        rec.text("edit_raw.txt", result.raw, i)
        rec.image("candidate_raw.png", result.rgb, i)

        t0 = time.perf_counter()
        cand, problems = checks.resize_to(result.rgb, rgb.shape[:2])
        found = self._find_target(rgb, cand, enh, mask_init, mask_anchor, it)
        lap("segment", t0)
        t0 = time.perf_counter()
        others = np.any([d.mask for d in found], axis=0) if found else np.zeros_like(mask_init)
        framing = checks.estimate_framing(rgb, cand, ~grow(mask_init | others, cfg.mask_margin_px))
        if framing is None:
            problems.append("framing could not be verified: too few consistent background features")
        elif checks.framing_changed(framing, cfg):
            note = checks.describe_framing(framing)
            if cfg.framing == "refuse" or framing.scale_change > cfg.max_reregister_scale_change:
                problems.append(note)
            else:
                cand, uncovered = checks.reregister(rgb, cand, framing)
                it.registered = True
                it.checks.append(f"{note}; re-registered ({100 * uncovered:.1f} % of the view uncovered)")
                found = self._find_target(rgb, cand, enh, mask_init, mask_anchor, it)
        if enh.group:
            problems += group.count_problems(found, group_size, enh.target)
            mask_goal = np.any([d.mask for d in found], axis=0) if found and not problems else None
        else:
            alike = checks.like_the_target(found, rgb, mask_init, cand)
            if len(alike) < len(found):
                areas = ", ".join(str(d.area_px) for d in found)
                it.checks.append(
                    f"target '{enh.target}' matched {len(found)} regions (areas {areas} px): took the one "
                    f"of the target's size ({alike[0].area_px} px, {int(mask_init.sum())} px before)"
                )
            found = alike  # each cut to what is new in it (a ball on a plate of its colour is one region with it)
            problems += checks.target_count_problems(found, enh.target)
            mask_goal = found[0].mask if len(found) == 1 else None
        if mask_goal is not None:
            exclude = grow(mask_init | mask_goal, cfg.mask_margin_px)
            problems += checks.background_problems(rgb, cand, exclude, cfg)
            problems += checks.target_motion_problems(rgb, cand, mask_init, mask_goal, cfg)
        it.checks.extend(problems)
        lap("checks", t0)
        rec.image("candidate.png", cand, i)
        if mask_goal is None:
            it.verdict = Verdict(False, tuple(problems), self.vlm.correct(it.prompt, problems), source="checks")
            rec.json("verdict.json", it.verdict, i)
            return None

        overlay = synthesize(rgb, cand, mask_goal, self.config.overlay_alpha)
        rec.image("mask_goal.png", mask_goal, i)
        rec.image("overlay.png", overlay, i)
        if problems:
            it.verdict = Verdict(False, tuple(problems), self.vlm.correct(it.prompt, problems), source="checks")
        else:
            t0 = time.perf_counter()
            request = ReflectionRequest(
                instruction,
                it.prompt,
                overlay,
                rgb,
                cand,
                mask_init,
                mask_goal,
                enh.target,
                enh.reference,
                depth_init=frame.depth,
            )
            try:
                it.verdict = self.vlm.reflect(request)
            except ProviderError as e:
                it.failure, it.failure_kind = f"reflector: {e}", e.kind
                rec.text("reflect_raw.txt", e.raw, i)
            lap("reflect", t0)
        if it.verdict is not None:
            rec.json("verdict.json", it.verdict, i)
        return _Candidate(cand, mask_goal, result, it)


def _by_iterations(iterations: list[Iteration]) -> list[str]:
    """Each distinct reason once, with the iterations that gave it: 'iterations 1-3: target missing ...'."""
    seen: dict[str, list[int]] = {}
    for it in iterations:
        for r in _reasons(it):
            seen.setdefault(r, []).append(it.index)
    out = []
    for reason, its in seen.items():
        runs = its[0] == its[-1] - len(its) + 1 and len(its) > 1
        which = (
            f"iterations {its[0]}-{its[-1]}"
            if runs
            else f"iteration{'s' if len(its) > 1 else ''} " + ", ".join(map(str, its))
        )
        out.append(f"{which}: {reason}")
    return out


def _reasons(it: Iteration) -> list[str]:
    if it.failure is not None:
        return [it.failure]
    if it.verdict is not None and not it.verdict.valid:
        return list(it.verdict.reasons) or ["reflector said invalid without reasons"]
    return []
