"""The run record (summary.json from its model, report.html, stage seconds) and the start-up check that names a
missing optional package."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydantic import ValidationError

from drivers.optional import missing_package
from pipeline.config import PipelineConfig
from pipeline.reasoning.factory import preflight
from runtime.config import StateBudgets
from runtime.devices import missing_device_packages
from runtime.run.record import RunRecord
from runtime.run.summary import SCHEMA_VERSION, RunSummary
from runtime.supervision.states import State, StateMachine


def test_record_writes_summary_report_and_stage_seconds(tmp_path):
    rec = RunRecord(tmp_path / "run", "r1")
    sm = StateMachine(StateBudgets())
    sm.add_listener(rec.on_transition)
    sm.advance(State.CAPTURING)
    rec.image("capture", np.full((20, 30, 3), 200, np.uint8))
    rec.image("mask", np.eye(20, 30, dtype=bool))
    rec.summary.instruction = "put <b>it</b> there"
    sm.fail("camera timeout")
    rec.finish(sm.state.value, sm.reason)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["schema_version"] == SCHEMA_VERSION and RunSummary.model_validate(summary) == rec.summary
    assert summary["status"] == "FAILED" and summary["reason"] == "camera timeout"
    assert set(summary["stage_seconds"]) == {"capturing"} and summary["images"] == ["capture.png", "mask.png"]
    assert [(t["previous"], t["state"]) for t in summary["transitions"]] == [
        ("IDLE", "CAPTURING"),
        ("CAPTURING", "FAILED"),
    ]
    html = (tmp_path / "run" / "report.html").read_text()
    assert "put &lt;b&gt;it&lt;/b&gt; there" in html and 'src="capture.png"' in html


def test_a_section_of_the_wrong_shape_is_refused_when_it_is_set(tmp_path):
    rec = RunRecord(tmp_path / "run", "r1")
    with pytest.raises(ValidationError, match="seed"):
        rec.summary.seed = "seven"
    with pytest.raises(ValidationError, match="no attribute"):
        rec.summary.confirmed_by = "cli"  # the old layout's key: not a field any more


def test_a_missing_optional_package_is_named_at_start_up(monkeypatch):
    assert missing_package("json", "json", "x") is None
    problem = missing_package("no_such_sdk.wrapper", "no-such-sdk", "robot.kind xarm7")
    assert (
        problem == "robot.kind xarm7 needs the package no-such-sdk (import no_such_sdk.wrapper), which is not installed"
    )
    import pipeline.reasoning.factory as factory

    monkeypatch.setitem(factory.PACKAGES, "dinov2", (("no_such_torch", "no-such-torch"),))
    problems = preflight(PipelineConfig(features="dinov2"))
    assert problems == [
        "pipeline.features = dinov2 needs the package no-such-torch (import no_such_torch), which is not installed"
    ]
    assert preflight(PipelineConfig()) == []  # offline backends need nothing optional


def test_the_sdks_a_hardware_profile_needs_are_checked(sim_config_path, monkeypatch):
    import runtime.devices as devices
    from runtime.config import load_profile

    lab = load_profile(sim_config_path.parent / "lab.yaml")
    monkeypatch.setitem(devices.SDKS, "xarm7", ("no_such_xarm", "xarm-python-sdk"))
    assert missing_device_packages(lab) == [
        "robot.kind xarm7 needs the package xarm-python-sdk (import no_such_xarm), which is not installed"
    ]
    assert missing_device_packages(load_profile(sim_config_path)) == []
