"""What a node acts on: every payload is checked for size, encoding, plain JSON, schema version, stamp and strict
types before any handler sees it, and refused with a reason a person can read."""

from __future__ import annotations

import json

import pytest

from runtime.messaging.messages import (
    MAX_AGE_S,
    MAX_PAYLOAD_BYTES,
    Command,
    Confirm,
    EStop,
    Heartbeat,
    MessageRefused,
    decode,
)
from runtime.messaging.throttle import Throttle

NOW = 1.75e9


def payload(**fields) -> bytes:
    return json.dumps({"v": 1, "stamp_s": NOW, **fields}).encode()


CONFIRM = {"plan_id": "p1", "source": "console"}


def test_a_good_message_reads():
    assert decode(Confirm, payload(**CONFIRM), NOW) == Confirm(stamp_s=NOW, **CONFIRM)


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (b"", "empty payload"),
        (b"x" * (MAX_PAYLOAD_BYTES + 1), f"payload of {MAX_PAYLOAD_BYTES + 1} bytes"),
        (b'{"v": 1, "plan_id": "\xff"}', "not UTF-8 (byte 21"),
        (b"STOP STOP STOP", "not JSON: expecting value"),
        (b"[1, 2]", "not a JSON object but list"),
        (b"[" * 5000 + b"]" * 5000, "nested too deeply"),
        (b'{"v": 1, "stamp_s": NaN}', "NaN is not a JSON number"),
        (b'{"v": 1, "stamp_s": 1e999}', "out of range"),
        (b'{"v": 1, "seq": ' + b"9" * 6000 + b"}", "not JSON: exceeds the limit"),
        (b'{"v": 1, "approve": false, "approve": true}', "key 'approve' appears twice"),
        (b'{"v": 1, "plan_id": "\\ud800"}', "lone surrogate"),
    ],
)
def test_unreadable_payloads_are_refused_with_the_problem(raw, reason):
    with pytest.raises(MessageRefused) as refused:
        decode(Confirm, raw, NOW)
    assert reason.lower() in str(refused.value).lower()


@pytest.mark.parametrize(
    ("fields", "reason"),
    [
        ({"v": 99}, "schema version 99 unknown (this node reads v 1)"),
        ({"v": "1"}, "schema version '1' unknown"),
        ({"v": True}, "schema version True unknown"),
        ({"stamp_s": 0}, "stamp_s 0 is not a time"),
        ({"stamp_s": -5.0}, "stamp_s -5.0 is not a time"),
        ({"stamp_s": NOW + 3600}, "stamped 3600.0 s in the future"),
        ({"stamp_s": NOW - MAX_AGE_S - 1}, f"stale: stamped {MAX_AGE_S + 1:.1f} s ago"),
        ({"stamp_s": "soon"}, "stamp_s: input should be a valid number"),
        ({"approve": "false"}, "approve: input should be a valid boolean"),
        ({"approve": 0}, "approve: input should be a valid boolean"),
        ({"plan_id": 7}, "plan_id: input should be a valid string"),
        ({"plan_id": "p" * 65}, "plan_id: string should have at most 64 characters"),
        ({"extra": 1}, "extra: extra inputs are not permitted"),
    ],
)
def test_versions_stamps_and_types_are_checked(fields, reason):
    with pytest.raises(MessageRefused) as refused:
        decode(Confirm, payload(**{**CONFIRM, **fields}), NOW)
    assert reason in str(refused.value)


def test_a_message_without_version_or_stamp_is_refused():
    with pytest.raises(MessageRefused, match="no schema version v"):
        decode(Confirm, json.dumps({"stamp_s": NOW, **CONFIRM}).encode(), NOW)
    with pytest.raises(MessageRefused, match="stamp_s: field required"):
        decode(Confirm, json.dumps({"v": 1, **CONFIRM}).encode(), NOW)


def test_safety_messages_ignore_fields_a_newer_sender_adds():
    estop = decode(EStop, payload(source="pendant", reason="pressed", severity="high", zone=3), NOW)
    assert estop == EStop(stamp_s=NOW, source="pendant", reason="pressed")
    beat = decode(Heartbeat, payload(node="pendant", kind="estop", seq=4, battery=0.8), NOW)
    assert beat.seq == 4
    with pytest.raises(MessageRefused, match="extra inputs are not permitted"):  # an action is never a guess
        decode(Command, payload(action="run", instruction="x", priority="high"), NOW)


def test_command_kinds_and_sizes_are_bounded():
    with pytest.raises(MessageRefused, match="action: input should be 'run', 'abort' or 'reset'"):
        decode(Command, payload(action="fly"), NOW)
    with pytest.raises(MessageRefused, match="instruction: string should have at most 1000 characters"):
        decode(Command, payload(action="run", instruction="x" * 1001), NOW)
    with pytest.raises(MessageRefused, match="seq: input should be greater than or equal to 0"):
        decode(Heartbeat, payload(node="n", kind="estop", seq=-1), NOW)


def test_a_flood_of_refusals_is_told_a_few_times_with_the_count():
    clock = [0.0]
    throttle = Throttle(per_period=3, period_s=1.0, clock=lambda: clock[0])
    told: list[str] = []
    for i in range(1000):
        throttle.tell(f"refused {i}", told.append)
    assert told == ["refused 0", "refused 1", "refused 2"]
    clock[0] = 1.5
    throttle.tell("refused 1000", told.append)
    assert told[-1] == "refused 1000 (997 earlier notices held back)"
