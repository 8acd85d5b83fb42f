"""What a campaign runs: typed cases (scene, instruction, seed, trial, task and action labels, how the simulator
judges the outcome), expanded from task names.

A task name is one of
- a named task scene (TASKS below, one per scene of configs/scenes that has a task): its instruction on the scene
  placed by `sim_seed(seed, trial)`;
- `gen`: generated cases (drivers.sim.generate), the seed being the case's seed, its own instruction;
- `gen-all`: every instruction a generated scene offers (one case per action and object), for per-action tables.
Other issues add cases by adding TaskSpec entries (a new scene with its own truth rule) or their own expansion:
the campaign, the worker and the table only see `Case`.
"""

from __future__ import annotations

from collections.abc import Iterable

from pydantic import BaseModel, ConfigDict

GENERATED, GENERATED_ALL = "gen", "gen-all"
TRIAL_STRIDE = 100_000  # a named task's trials place its scene with seeds seed, seed + STRIDE, ...
# how the simulator judges a generated action (runtime.campaign.truth.RULES); a place: its centre alone
GENERATED_TRUTH = {"rotate": "goal_turn", "stand_up": "stood_up", "push": "goal_upright", "close": "hinge_shut"}


class TaskSpec(BaseModel):
    """A named task: the scene, what to ask, the object it moves and how the simulator judges it done."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    scene: str
    instruction: str
    action: str  # e.g. "place in", "stand up", "close"
    target: str | None  # the scene object the instruction moves (its lid's box for "close")
    truth: str = "goal_error"  # a rule of runtime.campaign.truth.RULES


TASKS: dict[str, TaskSpec] = {
    "tabletop": TaskSpec(
        scene="tabletop", instruction="put the red block on the white plate", action="place on", target="red_block"
    ),
    "pick_place": TaskSpec(
        scene="pick_place", instruction="put the red box on the white plate", action="place on", target="red_box"
    ),
    "block_scale": TaskSpec(
        scene="block_scale",
        instruction="put the yellow block on the black scale",
        action="place on",
        target="yellow_block",
    ),
    "tomato_pan": TaskSpec(
        scene="tomato_pan", instruction="put the red ball in the pan", action="place in", target="tomato"
    ),
    "bottle_standup": TaskSpec(
        scene="bottle_standup",
        instruction="stand the green bottle up",
        action="stand up",
        target="bottle",
        truth="stood_up",
    ),
    "close_lid": TaskSpec(
        scene="close_lid", instruction="close the blue chest", action="close", target="box", truth="hinge_shut"
    ),
    "table_sweep": TaskSpec(
        scene="table_sweep",
        instruction="sweep the screws into the dustpan",
        action="sweep",
        target=None,
        truth="task_done",
    ),
    "pick_up": TaskSpec(
        scene="pick_up", instruction="pick up the red cup", action="lift", target="red_cup", truth="task_done"
    ),
    "take_off": TaskSpec(
        scene="take_off",
        instruction="take the red block off the stand",
        action="take off",
        target="red_block",
        truth="task_done",
    ),
    "take_off_plate": TaskSpec(
        scene="take_off",
        instruction="take the orange plate out of the dish rack",
        action="take off",
        target="plate",
        truth="task_done",
    ),
}


class Case(BaseModel):
    """One run of a campaign. `id` names its run folder, so it is unique within a campaign and stable across
    resumes."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    task: str  # the table's task label
    scene: str  # sim.scene: a name, a scene file, or gen:SEED
    instruction: str
    seed: int  # the campaign's seed
    trial: int
    sim_seed: int  # sim.seed of the run
    action: str  # the table's action label
    target: str | None = None  # the scene object that should move (simulator truth)
    truth: str = "goal_error"
    in_grammar: bool = True  # False: a sentence the run must refuse before it starts
    variant: str = ""  # tells apart cases of one (task, seed, trial), e.g. gen-all's actions

    @property
    def id(self) -> str:
        suffix = f"-{self.variant}" if self.variant else ""
        return f"{self.task}-s{self.seed:04d}-t{self.trial:02d}{suffix}"


def sim_seed(seed: int, trial: int) -> int:
    """The placement seed of a named task's trial: trial 0 is the seed itself (`goalvla run --seed SEED`)."""
    return seed + TRIAL_STRIDE * trial


def _generated(seed: int, trial: int, every_action: bool) -> list[Case]:
    from drivers.sim.generate import generate_case

    case = generate_case(seed)
    tasks = case.tasks if every_action else (case.task,)
    out = []
    for i, t in enumerate(tasks):
        action = t.action.replace("_", " ") + (f" {t.relation}" if t.relation else "")
        out.append(
            Case(
                task=GENERATED_ALL if every_action else GENERATED,
                scene=case.scene_name,
                instruction=t.instruction,
                seed=seed,
                trial=trial,
                sim_seed=trial,
                action=action,
                target=t.target,
                truth=GENERATED_TRUTH.get(t.action, "goal_error"),
                in_grammar=t.in_grammar,
                variant=f"a{i:02d}" if every_action else "",
            )
        )
    return out


def expand(tasks: Iterable[str], seeds: Iterable[int], trials: int) -> list[Case]:
    """Every case of the campaign, task by task, seed by seed, trial by trial; ValueError names an unknown task."""
    seeds = list(seeds)
    cases: list[Case] = []
    for task in tasks:
        if task not in TASKS and task not in (GENERATED, GENERATED_ALL):
            known = ", ".join([*TASKS, GENERATED, GENERATED_ALL])
            raise ValueError(f"unknown task {task!r}; known: {known}")
        for seed in seeds:
            for trial in range(trials):
                if task in (GENERATED, GENERATED_ALL):
                    cases += _generated(seed, trial, task == GENERATED_ALL)
                    continue
                spec = TASKS[task]
                cases.append(
                    Case(
                        task=task,
                        scene=spec.scene,
                        instruction=spec.instruction,
                        seed=seed,
                        trial=trial,
                        sim_seed=sim_seed(seed, trial),
                        action=spec.action,
                        target=spec.target,
                        truth=spec.truth,
                    )
                )
    ids = [c.id for c in cases]
    if len(set(ids)) != len(ids):
        raise ValueError("the campaign names a case twice (a task or a seed given twice?)")
    return cases
