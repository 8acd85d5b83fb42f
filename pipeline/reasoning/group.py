"""A group target (the screws of a sweep): every instance a plural phrase names is the target, as one union mask.

Why a union and not one mask per instance: what a sweep asks of the goal image is where the group ends up (in the
dustpan), not where each screw goes. Like instances cannot be told apart between two images, and a sweep does not
keep their arrangement, so there is no per-instance motion to recover; the group's motion is its parts' centroid
motion (pipeline.grounding.group), and the count of instances is what verification checks (how many ended inside).
"""

from __future__ import annotations

import numpy as np

from pipeline.perception.segmenter import Detection
from pipeline.reasoning.types import ReasoningError


def initial_union(found: list[Detection], phrase: str) -> np.ndarray:
    """The union of a group's instances in the initial image; ReasoningError when there is none."""
    if not found:
        reason = f"target '{phrase}' matches no object in the initial image (needs at least one)"
        raise ReasoningError(reason, [reason])
    return np.any([d.mask for d in found], axis=0)


def count_problems(found: list[Detection], group_size: int | None, phrase: str) -> list[str]:
    """A goal image must show the group (touching instances may merge, walls may hide some), never more of it."""
    if not found:
        return [f"target '{phrase}' missing from the candidate"]
    if group_size is not None and len(found) > group_size:
        return [f"target '{phrase}' appears {len(found)} times in the candidate, {group_size} in the initial image"]
    return []
