"""Data of stage 1 (goal state reasoning): requests and replies of the model-facing steps, and the GoalState."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.perception.depth import RelativeDepth


class ReasoningError(RuntimeError):
    """No validated goal: the message and `reasons` say why, iteration by iteration."""

    def __init__(self, message: str, reasons: list[str] | None = None) -> None:
        super().__init__(message)
        self.reasons = list(reasons or [])


@dataclass(frozen=True)
class Enhancement:
    """The enhancer's output: an editing prompt and the phrases that name the target (and reference) objects.

    `anchor` names the object the target is a part of when only that part moves (a box whose lid closes): the
    anchor stays put, and grounding uses where the part meets it as the hinge. `group`: the target phrase names
    several like objects (the screws of a sweep), every instance is the target. `tool`: what the robot moves the
    target with (a brush); it ends where it was.
    """

    prompt: str
    target: str
    reference: str | None = None
    raw: str = ""
    anchor: str | None = None
    tool: str | None = None
    group: bool = False


@dataclass(frozen=True)
class EditRequest:
    """One editing call. Cloud editors use rgb + prompt; the offline editor also needs the metric view (and,
    when known, the camera's pose in the robot base frame, to keep goals in the arm's reach)."""

    rgb: np.ndarray
    prompt: str
    depth_m: np.ndarray | None = None
    intrinsics: CameraIntrinsics | None = None
    T_base_camera: np.ndarray | None = None


@dataclass(frozen=True)
class EditResult:
    """A candidate goal image; `raw` is what the provider said (text parts, finish reason) for the record.

    The offline editor also returns the goal's relative depth and the rigid motion it applied
    (T_goal_init in the camera frame: x_goal = R x_init + t), which benchmarks compare grounding against.
    """

    rgb: np.ndarray
    raw: str = ""
    relative_depth: RelativeDepth | None = None
    T_goal_init_camera: np.ndarray | None = None


@dataclass(frozen=True)
class Verdict:
    valid: bool
    reasons: tuple[str, ...]
    revised_prompt: str | None = None
    source: str = "reflector"  # "checks" when the geometric checks refused before the reflector was asked
    raw: str = ""


@dataclass(frozen=True)
class ReflectionRequest:
    """What the reflector judges: the synthesis overlay (initial image + semi-transparent goal object)."""

    instruction: str
    prompt: str
    overlay: np.ndarray
    rgb_init: np.ndarray
    rgb_goal: np.ndarray
    mask_init: np.ndarray
    mask_goal: np.ndarray
    target: str
    reference: str | None = None
    depth_init: np.ndarray | None = None  # the capture's depth (metres), for a reflector that segments the capture


@dataclass
class Iteration:
    """One pass of Reflection-through-Synthesis, kept whether or not it produced a usable candidate."""

    index: int
    prompt: str
    verdict: Verdict | None = None
    failure: str | None = None  # provider failure, when there was no candidate or no verdict
    failure_kind: str | None = None  # ProviderError.kind
    checks: list[str] = field(default_factory=list)
    registered: bool = False  # the candidate was re-registered onto the initial framing
    seconds: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class GoalState:
    """Stage 1 output: the goal image with the target masks in both views and the goal's relative depth.

    `validated` is False only when the operator explicitly allowed an unvalidated goal.
    """

    instruction: str
    prompt: str
    target: str
    rgb_init: np.ndarray
    rgb_goal: np.ndarray
    mask_init: np.ndarray
    mask_goal: np.ndarray
    depth_goal: RelativeDepth
    iterations: tuple[Iteration, ...]
    validated: bool
    T_goal_init_camera: np.ndarray | None = None  # only from the offline editor (known by construction)
    seconds: dict[str, float] = field(default_factory=dict)
    mask_anchor: np.ndarray | None = None  # initial-view mask of the object the moving part is attached to
    # a group target (the screws): how many instances the initial image shows; mask_init/mask_goal are their union
    group_size: int | None = None
    tool: str | None = None  # what the target is moved with (a sweep's brush) ...
    mask_tool: np.ndarray | None = None  # ... and its initial-view mask
    reference: str | None = None  # with a group or a tool: the object the target goes into (the dustpan) ...
    mask_reference: np.ndarray | None = None  # ... and its initial-view mask

    @property
    def prompts(self) -> tuple[str, ...]:
        return tuple(it.prompt for it in self.iterations)

    @property
    def verdicts(self) -> tuple[Verdict | None, ...]:
        return tuple(it.verdict for it in self.iterations)
