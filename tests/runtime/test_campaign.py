"""`goalvla eval`: cases from task names, the simulator's truth rules, the table by task and action, gathering a
returned run folder whole or not at all, resuming; and a small real campaign run on worker processes and on a local
Ray instance, which must write the same table."""

from __future__ import annotations

import io
import tarfile

import pytest
from rich.console import Console

from runtime.campaign.campaign import CampaignError, CampaignSpec, finished, read_outcome, run_campaign
from runtime.campaign.cases import GENERATED, GENERATED_ALL, TASKS, Case, expand, sim_seed
from runtime.campaign.results import RESULT_FILE, CampaignTable, CaseResult, is_load_fault
from runtime.campaign.truth import judge
from runtime.campaign.worker import unpack
from runtime.run.summary import RunSummary, SimTruthRecord, TaskTruthRecord, TransitionRecord


def case(task="tabletop", seed=0, trial=0, **kw) -> Case:
    spec = TASKS[task]
    base = dict(task=task, scene=spec.scene, instruction=spec.instruction, seed=seed, trial=trial,
                sim_seed=sim_seed(seed, trial), action=spec.action, target=spec.target, truth=spec.truth)  # fmt: skip
    return Case(**{**base, **kw})


def summary(status="DONE", failed_in=None, truth=None, wall=10.0) -> RunSummary:
    s = RunSummary(run_id="r", status=status, wall_s=wall, sim_truth=truth)
    states = ["CAPTURING", "REASONING", "GROUNDING", "PLANNING", "AWAITING_CONFIRM", "EXECUTING", "VERIFYING"]
    path = states[: states.index(failed_in.upper()) + 1] if failed_in else states
    previous = "IDLE"
    for state in [*path, status if status != "DONE" else "DONE"]:
        s.transitions = [*s.transitions, TransitionRecord(previous=previous, state=state, reason="", stamp_s=0.0)]
        previous = state
    return s


def moved(target: str, error: float) -> SimTruthRecord:
    return SimTruthRecord(object_displacement_m={target: 0.2}, hinge_deg={}, target=target, target_goal_error_m=error)


def test_cases_expand_task_by_seed_by_trial_with_stable_unique_ids():
    cases = expand(["tomato_pan", "close_lid"], [3, 4], trials=2)
    assert len(cases) == 8 and len({c.id for c in cases}) == 8
    first = cases[0]
    assert (first.id, first.scene, first.sim_seed, first.target) == ("tomato_pan-s0003-t00", "tomato_pan", 3, "tomato")
    assert cases[1].sim_seed == sim_seed(3, 1) != 3  # a second trial places the scene anew
    assert {c.truth for c in cases if c.task == "close_lid"} == {"hinge_shut"}
    assert expand(["tomato_pan"], [3], 1)[0] == first  # the same campaign names the same cases (resume)


def test_generated_cases_carry_their_scene_action_and_target():
    (one,) = expand([GENERATED], [5], 1)
    assert one.scene == "gen:5" and one.target and one.action and one.task == GENERATED
    every = expand([GENERATED_ALL], [5], 1)
    assert len(every) > 1 and len({c.id for c in every}) == len(every) and len({c.action for c in every}) > 1
    outside = expand([GENERATED], [11], 1)[0]
    assert not outside.in_grammar  # seed 11's sentence is outside the grammar: a run must refuse it


def test_unknown_or_repeated_tasks_are_refused_with_the_known_ones():
    with pytest.raises(ValueError, match=r"unknown task 'tomato'.*tomato_pan"):
        expand(["tomato"], [0], 1)
    with pytest.raises(ValueError, match="twice"):
        expand(["close_lid", "close_lid"], [0], 1)


def test_truth_judges_the_target_where_it_ended_not_the_verdict():
    c = case()
    assert judge(c, summary(truth=moved("red_block", 0.01))) is True
    assert judge(c, summary(truth=moved("red_block", 0.05))) is False  # verified, but 5 cm off: a false success
    assert judge(c, summary(truth=moved("blue_block", 0.0))) is False  # another object moved there
    assert judge(c, summary("FAILED", "grounding")) is False  # the arm never moved: not done
    assert judge(c, summary("FAILED", "executing")) is None  # stopped while moving, before the truth was taken
    lid = case("close_lid")
    shut = SimTruthRecord(object_displacement_m={}, hinge_deg={"box_hinge": 4.0})
    open_ = SimTruthRecord(object_displacement_m={}, hinge_deg={"box_hinge": 40.0})
    assert judge(lid, summary(truth=shut)) is True and judge(lid, summary("FAILED", "verifying", open_)) is False


def test_the_sweep_lift_and_take_off_tasks_are_judged_by_their_own_truth():
    for task in ("table_sweep", "pick_up", "take_off", "take_off_plate"):
        c = case(task)
        done = SimTruthRecord(
            object_displacement_m={}, hinge_deg={}, task=TaskTruthRecord(action="sweep", done=True, detail="5 of 5")
        )
        short = done.model_copy(update={"task": TaskTruthRecord(action="sweep", done=False, detail="3 of 5")})
        assert judge(c, summary(truth=done)) is True and judge(c, summary(truth=short)) is False
        assert judge(c, summary(truth=SimTruthRecord(object_displacement_m={}, hinge_deg={}))) is False
        assert judge(c, summary("FAILED", "planning")) is False


def test_a_turn_and_a_stand_up_are_judged_by_the_shape_a_push_by_not_tipping():
    def turned(turn: float, tilt: float, error: float = 0.01) -> SimTruthRecord:
        return moved("bottle", error).model_copy(update={"target_turn_error_deg": turn, "target_tilt_error_deg": tilt})

    def stood(turn: float, tilt: float, upright: bool, error: float = 0.01) -> SimTruthRecord:
        task = TaskTruthRecord(action="stand_up", done=upright, detail="")
        return turned(turn, tilt, error).model_copy(update={"task": task})

    stand_up = case("bottle_standup")
    assert stand_up.truth == "stood_up"
    assert judge(stand_up, summary(truth=stood(5.0, 5.0, True))) is True
    assert judge(stand_up, summary(truth=stood(80.0, 80.0, False))) is False  # where it should be, still lying down
    assert judge(stand_up, summary(truth=stood(5.0, 5.0, True, error=0.05))) is False
    # on its neck: as the grounded motion (turned end for end) had it, but not stood up
    assert judge(stand_up, summary(truth=stood(1.0, 1.0, False))) is False
    push = case(action="push", target="bottle", truth="goal_upright")
    assert judge(push, summary(truth=turned(40.0, 3.0))) is True  # twisted along the way: no matter
    assert judge(push, summary(truth=turned(40.0, 30.0))) is False  # tipped over
    place = case(target="bottle")
    assert judge(place, summary(truth=turned(80.0, 80.0))) is True  # a place judges the centre alone
    by_action = {c.action.split()[0]: c.truth for c in expand([GENERATED_ALL], range(20, 32), 1)}
    assert by_action["rotate"] == "goal_turn" and by_action["stand"] == "stood_up"
    assert by_action["push"] == "goal_upright"
    assert by_action["close"] == "hinge_shut" and by_action["place"] == "goal_error"


def test_a_run_this_machines_load_stopped_is_run_again_with_the_first_record_kept(
    tmp_path, monkeypatch, sim_config_path
):
    from runtime.campaign import worker

    starved = summary("FAILED", "executing")
    starved.reason = "stale joint state: none newer than 0.310 s"
    reasons = iter([starved, summary(truth=moved("red_block", 0.01))])
    attempts = []

    def attempt(c, profile, run_dir, contact, stepped):
        run_dir.mkdir(parents=True)
        (run_dir / "summary.json").write_text("{}")
        attempts.append(stepped)
        return CaseResult.of(c, next(reasons))

    monkeypatch.setattr(worker, "_attempt", attempt)
    monkeypatch.setattr(worker, "_refusal", lambda c, profile: None)
    run_dir = tmp_path / "tabletop-s0000-t00"
    result = worker.run_case(case(), sim_config_path, "ci", run_dir, stepped=True)
    assert attempts == [True, True] and result.verified and not result.load_fault
    assert result.ran_again_after.startswith("stale joint state") and result.load_1min is not None
    assert (run_dir / worker.EARLIER_ATTEMPT / "summary.json").is_file()
    assert CaseResult.read(run_dir) == result and [p.name for p in tmp_path.iterdir()] == [run_dir.name]
    table = CampaignTable.of([CaseResult.of(case(), starved), result])
    assert table.total.load_faults == 1
    late = "no fresh e-stop heartbeat (last 1.91 s ago, limit 1.0 s): not moving"
    assert is_load_fault("FAILED", late) and not is_load_fault("FAILED", "plan: no contact could be planned")


def test_a_stepped_campaign_runs_without_real_time_physics():
    from runtime.campaign.worker import profile_overrides

    stepped = profile_overrides(case(), "ci", True, stepped=True)
    assert stepped["sim"]["realtime"] is False and stepped["runtime"]["deadman_timeout_s"] == 1.0
    assert "realtime" not in profile_overrides(case(), "ci", True)["sim"]


def test_the_table_counts_false_successes_false_failures_and_where_failures_started():
    results = [
        CaseResult.of(case(seed=0), summary(truth=moved("red_block", 0.01), wall=8.0)),
        CaseResult.of(case(seed=1), summary(truth=moved("red_block", 0.09), wall=10.0)),  # false success
        CaseResult.of(case(seed=2), summary("FAILED", "verifying", moved("red_block", 0.01), 12.0)),  # false failure
        CaseResult.of(case(seed=3), summary("FAILED", "grounding", None, 4.0)),
        CaseResult.of(case("close_lid"), summary("FAILED", "planning", None, 6.0)),
        CaseResult.refused(case(seed=4), "wipe the table: outside the grammar"),
    ]
    table = CampaignTable.of(results)
    tabletop, close_lid = table.by_task
    assert (tabletop.group, tabletop.runs, tabletop.verified, tabletop.truly_done) == ("tabletop", 5, 2, 2)
    assert (tabletop.false_successes, tabletop.false_failures, tabletop.refused_before_start) == (1, 1, 1)
    assert tabletop.failed_in == {"before start": 1, "grounding": 1, "verifying": 1}
    assert tabletop.median_wall_s == 9.0 and tabletop.truth_unknown == 0  # grounding's failure moved nothing
    assert close_lid.failed_in == {"planning": 1} and table.total.runs == 6
    assert [r.group for r in table.by_action] == ["close", "place on"]


def _packed(case_id: str, with_result: bool) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as tar:
        for name, text in [("summary.json", "{}"), *([(RESULT_FILE, "{}")] if with_result else [])]:
            data = text.encode()
            info = tarfile.TarInfo(f"{case_id}/{name}")
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return buffer.getvalue()


def test_a_returned_run_folder_is_gathered_whole_or_not_at_all(tmp_path):
    assert (unpack("a", _packed("a", True), tmp_path) / RESULT_FILE).is_file()
    with pytest.raises(ValueError, match=r"no result\.json"):
        unpack("b", _packed("b", False), tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]  # nothing half-gathered, no temporary left


def test_finished_runs_are_found_and_another_campaign_is_not_mixed_in(tmp_path, sim_config_path):
    spec = CampaignSpec(name="c", config=str(sim_config_path), tasks=("tabletop",), seeds=(0, 1), trials=1)
    cases = spec.cases()
    done = CaseResult.of(cases[0], summary(truth=moved("red_block", 0.01)))
    (tmp_path / "runs" / cases[0].id).mkdir(parents=True)
    (tmp_path / "runs" / cases[0].id / RESULT_FILE).write_text(done.model_dump_json())
    (tmp_path / "runs" / cases[1].id).mkdir()  # crashed: a folder without result.json runs again
    assert list(finished(cases, tmp_path / "runs")) == [cases[0].id]
    (tmp_path / "campaign.json").write_text(spec.model_copy(update={"trials": 2}).model_dump_json())
    with pytest.raises(CampaignError, match="another campaign"):
        run_campaign(spec, tmp_path, pool=None, console=Console(quiet=True))


@pytest.mark.slow
def test_worker_processes_and_a_local_ray_instance_write_the_same_table(tmp_path, sim_config_path):
    """Two cases (a whole tabletop run, a generated sentence outside the grammar refused before start) on two
    worker processes and on a local Ray instance: the same outcomes (timings aside); run again, nothing is redone."""
    from runtime.campaign.pools import ProcessPool, RayPool

    spec = CampaignSpec(name="ci", config=str(sim_config_path), tasks=("tabletop", GENERATED), seeds=(11,), trials=1)
    quiet = Console(quiet=True)
    outcomes = {}
    for name, make in (("processes", lambda: ProcessPool(2)), ("ray", lambda: RayPool("local", 2))):
        pool = make()
        try:
            outcomes[name] = run_campaign(spec, tmp_path / name, pool, quiet)
        finally:
            pool.close()
    processes, ray = outcomes["processes"], outcomes["ray"]
    assert not processes.errors and not ray.errors, (processes.errors, ray.errors)
    assert processes.table.outcome() == ray.table.outcome()
    assert [(r.case.id, r.status, r.failed_in) for r in processes.results] == [
        (r.case.id, r.status, r.failed_in) for r in ray.results
    ]
    assert processes.table.total.refused_before_start == 1 and processes.table.total.runs == 2
    run = tmp_path / "ray" / "runs" / "tabletop-s0011-t00"
    assert (run / "summary.json").is_file() and (run / "report.html").is_file() and (run / "run.rrd").is_file()
    assert RunSummary.model_validate_json((run / "summary.json").read_text()).robot_id.startswith("eval-ci-")
    assert read_outcome(tmp_path / "ray").table == ray.table
    pool = ProcessPool(1)
    try:
        again = run_campaign(spec, tmp_path / "processes", pool, quiet)
    finally:
        pool.close()
    assert again.ran_now == 0 and again.table.outcome() == processes.table.outcome()


def test_a_stepped_campaigns_stages_step_the_runs_simulated_world():
    from types import SimpleNamespace

    from drivers.sim import SteppedClock
    from runtime.campaign.worker import build_stages

    world = object()
    assert build_stages("pipeline").clock is None
    for contact in ("pipeline", "oracle"):
        clock = build_stages(contact, stepped=True).clock(SimpleNamespace(world=world))
        assert isinstance(clock, SteppedClock) and clock.world is world


@pytest.mark.slow
def test_a_stepped_case_is_a_whole_run_judged_by_the_simulator(sim_config_path, tmp_path):
    from runtime.campaign.worker import run_case

    result = run_case(case("take_off", seed=5), sim_config_path, "c", tmp_path / "run", False, stepped=True)
    assert result.verified and result.truly_done, result.reason
    assert (tmp_path / "run" / RESULT_FILE).is_file()
