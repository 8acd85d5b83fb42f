"""Zenoh messaging: loopback sessions at a free port, schema validation, liveliness, config for the lab."""

from __future__ import annotations

import json
import time

import pytest
import zenoh
from pydantic import ValidationError
from runtime_helpers import wait_for

from runtime.config import ConfigError, ZenohConfig, load_profile
from runtime.messaging.bus import Bus, session_config
from runtime.messaging.messages import Confirm, EStop, Heartbeat, Keys, MessageRefused


def test_key_space():
    keys = Keys("xarm7_lab")
    assert keys.status == "goalvla/xarm7_lab/status"
    assert keys.image("goal") == "goalvla/xarm7_lab/images/goal"
    assert keys.heartbeat_of("estop-1") == "goalvla/xarm7_lab/heartbeat/estop-1"
    assert keys.confirm == "goalvla/xarm7_lab/confirm"


def test_messages_round_trip_and_reject_unknown_fields():
    now = time.time()
    msg = Confirm(stamp_s=now, plan_id="p-1", source="console")
    assert Confirm.decode(msg.encode()) == msg
    with pytest.raises(MessageRefused, match="extra: extra inputs are not permitted"):
        Confirm.decode(f'{{"v": 1, "stamp_s": {now}, "plan_id": "p", "source": "x", "extra": 1}}'.encode())
    with pytest.raises(MessageRefused, match="not UTF-8"):
        Confirm.decode(b"\x80\x04not json")
    with pytest.raises(ValidationError):  # senders are held to the schema too
        Confirm(stamp_s=now, plan_id="p", source="x", extra=1)


def test_two_nodes_talk_and_malformed_payloads_are_dropped(zenoh_cfg):
    with Bus(zenoh_cfg, "r1", "listen") as hub, Bus(zenoh_cfg, "r1", "connect") as node:
        got = []
        hub.subscribe(hub.keys.estop, EStop, lambda k, m: got.append(m))
        assert wait_for(lambda: _probe(node, got), period_s=0.05)  # the two sessions are connected
        node.publish(node.keys.estop, f'{{"v": 1, "stamp_s": {time.time()}}}'.encode())  # no source: invalid
        node.publish(node.keys.estop, EStop(stamp_s=time.time(), source="term"))
        # one publisher on one key delivers in order: once "term" is in, the invalid sample was handled before it
        assert wait_for(lambda: any(m.source == "term" for m in got))
        assert [m.source for m in got if m.source != "probe"] == ["term"]
        assert hub.refused[hub.keys.estop] == 1 and hub.handled[hub.keys.estop] >= 2


def _probe(node: Bus, got: list) -> bool:
    """Publish a probe; True once any has arrived."""
    node.publish(node.keys.estop, EStop(stamp_s=time.time(), source="probe"))
    return bool(got)


def test_liveliness_token_vanishes_when_the_node_closes(zenoh_cfg):
    with Bus(zenoh_cfg, "r1", "listen") as hub:
        changes = []
        hub.watch_liveliness(f"{hub.keys.alive}/**", lambda k, alive: changes.append((k.rsplit("/", 1)[-1], alive)))
        node = Bus(zenoh_cfg, "r1", "connect")
        node.declare_token(node.keys.alive_of("estop", "n1"))
        assert wait_for(lambda: ("n1", True) in changes)
        node.close()
        assert wait_for(lambda: ("n1", False) in changes)


def test_same_session_delivers_to_itself(zenoh_cfg):
    with Bus(zenoh_cfg, "r1", "listen") as hub:
        got = []
        hub.subscribe(f"{hub.keys.heartbeat}/**", Heartbeat, lambda k, m: got.append(k))
        hub.publish(hub.keys.heartbeat_of("x"), Heartbeat(stamp_s=time.time(), node="x", kind="estop", seq=1))
        assert wait_for(lambda: got == ["goalvla/r1/heartbeat/x"])


def test_default_is_loopback_without_scouting():
    conf = session_config(ZenohConfig(), "listen")
    assert conf["listen"]["endpoints"] == ["tcp/127.0.0.1:7447"]
    assert conf["scouting"]["multicast"]["enabled"] is False and conf["scouting"]["gossip"]["enabled"] is False


def test_plain_tcp_off_loopback_is_refused():
    with pytest.raises(ValidationError, match="loopback only"):
        ZenohConfig(endpoint="tcp/192.168.1.10:7447")
    with pytest.raises(ValidationError, match=r"needs runtime\.zenoh\.tls"):
        ZenohConfig(endpoint="tls/192.168.1.10:7447")


def test_lab_profile_uses_mutual_tls_and_access_control(sim_config_path):
    lab = load_profile(sim_config_path.parent / "lab.yaml").runtime
    assert lab.zenoh.endpoint.startswith("tls/") and lab.zenoh.tls.mutual
    assert lab.estop_node == "external"
    assert lab.zenoh.access_control["enabled"] is True
    assert lab.zenoh.access_control["default_permission"] == "deny"
    for role in ("listen", "connect"):
        conf = session_config(lab.zenoh, role)
        assert conf["transport"]["link"]["tls"]["enable_mtls"] is True
        zenoh.Config.from_json5(json.dumps(conf))  # Zenoh itself accepts the block (files are read at open)


def test_unknown_runtime_key_names_file(tmp_path, sim_config_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"include: {sim_config_path}\nruntime:\n  zenoh: {{endpoint: tcp/10.0.0.1:7447}}\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: runtime.zenoh: .*loopback only"):
        load_profile(bad)
