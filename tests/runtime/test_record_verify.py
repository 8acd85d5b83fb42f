"""Run records, verification arithmetic and the 'not available' refusal of a missing stage module."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from runtime.config import StateBudgets
from runtime.context import StageUnavailable
from runtime.record import RunRecord
from runtime.stages import require
from runtime.states import State, StateMachine
from runtime.verify import compare


def yaw(deg: float) -> np.ndarray:
    return Rotation.from_euler("z", deg, degrees=True).as_matrix()


def test_reached_goal_passes():
    c = np.array([0.1, 0.0, 0.8])
    v = compare(np.eye(3), np.array([0.2, 0, 0]), np.eye(3), np.array([0.21, 0, 0]), c, 0.03, 15.0)
    assert v.ok and v.position_error_m == pytest.approx(0.01)


def test_position_off_by_more_than_the_tolerance_fails_with_the_numbers():
    c = np.zeros(3)
    v = compare(np.eye(3), np.array([0.2, 0, 0]), np.eye(3), np.array([0.15, 0, 0]), c, 0.03, 15.0)
    assert not v.ok and "50 mm from the goal (tolerance 30)" in v.reason


def test_rotation_is_judged_only_when_the_goal_rotates():
    c = np.array([0.0, 0.0, 0.8])
    free_yaw = compare(np.eye(3), np.zeros(3), yaw(40), c - yaw(40) @ c, c, 0.03, 15.0)
    assert free_yaw.ok and free_yaw.rotation_error_deg == pytest.approx(40, abs=1e-6)
    goal_R = yaw(90)
    wrong = compare(goal_R, c - goal_R @ c, yaw(60), c - yaw(60) @ c, c, 0.03, 15.0)
    assert not wrong.ok and "rotation 30.0 deg off" in wrong.reason


def test_record_writes_summary_report_and_stage_seconds(tmp_path):
    rec = RunRecord(tmp_path / "run", "r1")
    sm = StateMachine(StateBudgets())
    sm.add_listener(rec.on_transition)
    sm.advance(State.CAPTURING)
    rec.image("capture", np.full((20, 30, 3), 200, np.uint8))
    rec.image("mask", np.eye(20, 30, dtype=bool))
    rec.note(instruction="put <b>it</b> there")
    sm.fail("camera timeout")
    rec.finish(sm.state.value, sm.reason)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "FAILED" and summary["reason"] == "camera timeout"
    assert set(summary["stage_seconds"]) == {"capturing"} and summary["images"] == ["capture.png", "mask.png"]
    html = (tmp_path / "run" / "report.html").read_text()
    assert "put &lt;b&gt;it&lt;/b&gt; there" in html and 'src="capture.png"' in html


def test_missing_module_is_reported_not_faked():
    with pytest.raises(StageUnavailable, match=r"pipeline\.nothing_here is not available .* the contact stage"):
        require("contact", "pipeline.nothing_here", "plan_contact")
    with pytest.raises(StageUnavailable, match="has no no_such_function"):
        require("verification", "runtime.verify", "compare", "no_such_function")
