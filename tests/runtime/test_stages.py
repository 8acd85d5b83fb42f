"""The real pipeline stages map refusals of the modules they call to readable FAILED reasons."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from pipeline.perception.depth import RelativeDepth
from pipeline.reasoning.types import GoalState
from runtime.devices import open_devices
from runtime.run.context import RunContext, StageError
from runtime.run.record import RunRecord
from runtime.run.stages import PipelineStages


@pytest.fixture
def sim(stepped_profile, tmp_path):
    with open_devices(stepped_profile) as dev:
        frame = dev.capture()
        yield stepped_profile, dev, frame, dev.camera.object_masks(), RunRecord(tmp_path / "run", "r")


def test_implausible_grounding_is_refused_and_recorded(sim):
    profile, dev, frame, masks, record = sim
    # a "goal" in which the red block has turned into the blue block: no consistent rigid motion explains it
    depth = RelativeDepth(np.nan_to_num(frame.depth, nan=0.0).astype(np.float32), "depth")
    goal = GoalState(
        instruction="x",
        prompt="x",
        target="red block",
        rgb_init=frame.rgb,
        rgb_goal=frame.rgb,
        mask_init=masks["red_block"],
        mask_goal=masks["blue_block"],
        depth_goal=depth,
        iterations=(),
        validated=True,
    )
    ctx = RunContext(profile, dev, "x", record, threading.Event(), frame0=frame, goal=goal)
    with pytest.raises(StageError, match=r"^grounding refused: "):
        PipelineStages().ground(ctx)
    assert record.summary.object_motion.ok is False and ctx.motion is None


def test_instruction_outside_the_grammar_fails_reasoning_with_the_grammar(sim):
    profile, dev, frame, _masks, record = sim
    ctx = RunContext(profile, dev, "make me a sandwich", record, threading.Event(), frame0=frame)
    with pytest.raises(StageError, match=r"place\|put\|move"):
        PipelineStages().reason(ctx)
