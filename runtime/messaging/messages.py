"""Wire format: the Zenoh key space `goalvla/<robot_id>/...` and one pydantic schema per JSON payload.

Payloads are JSON or image bytes (JPEG); nothing is ever pickled. `decode` is the one way in: a payload is read
only when it is small, UTF-8, plain JSON (no NaN, no repeated keys, no deep nesting), carries a schema version
this node knows and a plausible stamp, and matches its schema with strict types (`"false"` is not a boolean).
Anything else is refused with a reason a person can read (`MessageRefused`), never half-applied.

Versions: `v` changes only when a field changes meaning or goes. A newer sender may add fields without changing
`v`; the safety messages (estop, heartbeat) ignore fields they do not know, so an e-stop node one version ahead
still stops this runtime, while commands and confirms refuse them (an action is never taken on a guess).
"""

from __future__ import annotations

import json
import math
import time
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

SCHEMA_VERSION = 1
KNOWN_VERSIONS = frozenset({SCHEMA_VERSION})
MAX_PAYLOAD_BYTES = 64 * 1024  # every JSON message is far smaller; images travel as bytes with their own bound
MAX_AGE_S = 5.0  # a message stamped longer ago than this is stale (delayed, replayed or from a wrong clock)
MAX_AHEAD_S = 1.0  # how far a sender's clock may run ahead of ours
MAX_TEXT = 1000  # free text (an instruction, a reason)
MAX_NAME = 64  # names and ids (node, source, plan id)


class MessageRefused(ValueError):
    """A payload this node will not act on; str() is the reason, for the log and the operator."""


class Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    v: int = SCHEMA_VERSION
    stamp_s: float = Field(description="sender's wall clock (time.time) when sent")

    def encode(self) -> bytes:
        return self.model_dump_json().encode()

    @classmethod
    def decode(cls, payload: bytes, now: float | None = None):
        return decode(cls, payload, now)


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
    """Any sample on the estop key stops the robot, whatever its payload; this is what a readable one says."""

    model_config = ConfigDict(extra="ignore", frozen=True)
    source: str = Field(max_length=MAX_NAME)
    reason: str = Field("e-stop pressed", max_length=MAX_TEXT)


class Heartbeat(Message):
    model_config = ConfigDict(extra="ignore", frozen=True)
    node: str = Field(min_length=1, max_length=MAX_NAME)
    kind: Literal["estop", "console"]
    seq: int = Field(ge=0, lt=2**63)


class Confirm(Message):
    plan_id: str = Field(min_length=1, max_length=MAX_NAME)
    source: str = Field(max_length=MAX_NAME)
    approve: bool = True


class Command(Message):
    action: Literal["run", "abort", "reset"]
    instruction: str = Field("", max_length=MAX_TEXT)
    source: str = Field("", max_length=MAX_NAME)


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


# -- reading a payload -----------------------------------------------------------------------------------------
def _no_repeats(pairs: list[tuple[str, Any]]) -> dict:
    data = dict(pairs)
    if len(data) != len(pairs):
        seen: set[str] = set()
        repeated = next(k for k, _ in pairs if k in seen or seen.add(k))
        raise ValueError(f"key {repeated!r} appears twice")
    return data


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"number {text[:20]} is out of range")
    return value


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")


def printable(text: str, limit: int = 160) -> str:
    """Text from a payload, safe to log and show: bounded, control characters and lone surrogates escaped."""
    clipped = text if len(text) <= limit else text[:limit] + f"... ({len(text)} characters)"
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in clipped)


def describe_errors(e: ValidationError) -> str:
    """A validation error in a line: where and what, for the first few problems."""
    parts = []
    for err in e.errors()[:3]:
        where = printable(".".join(str(p) for p in err["loc"]), 60) or "payload"
        parts.append(f"{where}: {err['msg'].lower()}")
    more = e.error_count() - len(parts)
    return "; ".join(parts) + (f" (+{more} more)" if more > 0 else "")


def read_json(payload: bytes) -> dict:
    """The payload as a JSON object, or MessageRefused saying what is wrong with it."""
    if not payload:
        raise MessageRefused("empty payload")
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise MessageRefused(f"payload of {len(payload)} bytes (limit {MAX_PAYLOAD_BYTES})")
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError as e:
        raise MessageRefused(f"not UTF-8 (byte {e.start}: {payload[e.start : e.start + 4]!r})") from None
    try:
        data = json.loads(text, object_pairs_hook=_no_repeats, parse_float=_finite, parse_constant=_no_constant)
    except RecursionError:
        raise MessageRefused("not JSON: nested too deeply") from None
    except ValueError as e:  # JSONDecodeError, repeated keys, NaN/inf, integers beyond Python's digit limit
        raise MessageRefused(f"not JSON: {printable(str(e))}") from None
    if not isinstance(data, dict):
        raise MessageRefused(f"not a JSON object but {type(data).__name__}")
    try:  # a lone surrogate escape ("\\ud800") would break every later writer of the text
        json.dumps(data, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        raise MessageRefused("a string holds a lone surrogate escape (not Unicode text)") from None
    return data


def check_version_and_stamp(data: dict, now: float) -> None:
    if "v" not in data:
        raise MessageRefused("no schema version v")
    v = data["v"]
    if type(v) is not int or v not in KNOWN_VERSIONS:
        known = ", ".join(str(k) for k in sorted(KNOWN_VERSIONS))
        raise MessageRefused(f"schema version {printable(repr(v), 40)} unknown (this node reads v {known})")
    stamp = data.get("stamp_s")
    if type(stamp) not in (int, float):
        return  # the schema says what is wrong with it
    if stamp <= 0:
        raise MessageRefused(f"stamp_s {stamp} is not a time")
    if stamp > now + MAX_AHEAD_S:
        raise MessageRefused(f"stamped {stamp - now:.1f} s in the future (clocks may differ by {MAX_AHEAD_S} s)")
    if stamp < now - MAX_AGE_S:
        raise MessageRefused(f"stale: stamped {now - stamp:.1f} s ago (limit {MAX_AGE_S} s)")


def decode(schema: type[Message], payload: bytes, now: float | None = None) -> Message:
    """A checked message of `schema` from a payload, or MessageRefused with the reason. `now`: our wall clock."""
    data = read_json(payload)
    check_version_and_stamp(data, time.time() if now is None else now)
    try:
        return schema.model_validate(data, strict=True)
    except ValidationError as e:
        raise MessageRefused(f"not a valid {schema.__name__}: {describe_errors(e)}") from None
