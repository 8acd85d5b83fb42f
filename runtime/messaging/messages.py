"""Wire format: the Zenoh key space `goalvla/<robot_id>/...` and one pydantic schema per JSON payload.

Payloads are JSON (schema-validated on receipt, unknown fields rejected) or image bytes (PNG/JPEG); nothing is
ever pickled. A message that fails validation is dropped by the receiver and logged, never half-applied.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

SCHEMA_VERSION = 1


class Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    v: int = SCHEMA_VERSION
    stamp_s: float = Field(description="sender's wall clock (time.time) when sent")

    def encode(self) -> bytes:
        return self.model_dump_json().encode()

    @classmethod
    def decode(cls, payload: bytes):
        return cls.model_validate_json(payload)


class Status(Message):
    state: str
    previous: str = ""
    reason: str = ""
    run_id: str = ""
    plan_id: str = ""
    instruction: str = ""
    seconds_in_previous: float = 0.0


class Event(Message):
    level: Literal["info", "warning", "error"] = "info"
    text: str
    run_id: str = ""


class JointStateMsg(Message):
    names: list[str]
    q_rad: list[float]
    qd_rad_s: list[float]
    fault_code: int = 0
    gripper_width_m: float | None = None


class PlanSummary(Message):
    """What the operator confirms: the plan id and what the robot is about to do."""

    plan_id: str
    run_id: str
    instruction: str
    mode: str = ""  # grasp | push
    duration_s: float
    peak_joint_speed_rad_s: list[float]
    min_clearance_m: float | None = None  # guaranteed lower bound: every link passed the gate padded by this
    samples: int
    gate_ok: bool
    object_motion: dict = Field(default_factory=dict)  # translation_m, rotation_deg in the base frame


class EStop(Message):
    source: str
    reason: str = "e-stop pressed"


class Heartbeat(Message):
    node: str
    kind: Literal["estop", "console"]
    seq: int


class Confirm(Message):
    plan_id: str
    source: str
    approve: bool = True


class Command(Message):
    action: Literal["run", "abort", "reset"]
    instruction: str = ""
    source: str = ""


class Keys:
    """Key expressions of one robot; every node builds them from the same robot_id."""

    def __init__(self, robot_id: str) -> None:
        self.root = f"goalvla/{robot_id}"
        self.status = f"{self.root}/status"
        self.joint_state = f"{self.root}/joint_state"
        self.events = f"{self.root}/events"
        self.images = f"{self.root}/images"
        self.plan = f"{self.root}/plan"
        self.estop = f"{self.root}/estop"
        self.heartbeat = f"{self.root}/heartbeat"
        self.confirm = f"{self.root}/confirm"
        self.command = f"{self.root}/command"
        self.alive = f"{self.root}/alive"  # liveliness tokens: alive/<kind>/<node>

    def image(self, name: str) -> str:
        return f"{self.images}/{name}"

    def heartbeat_of(self, node: str) -> str:
        return f"{self.heartbeat}/{node}"

    def alive_of(self, kind: str, node: str) -> str:
        return f"{self.alive}/{kind}/{node}"
