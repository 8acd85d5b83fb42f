"""The console's side of the bus: the latest of everything the runtime publishes, fanned out to the pages, and
the operator's actions published as typed messages.

Fan-out never blocks a Zenoh callback: each page has its own bounded queue of encoded events, and a page that
falls that far behind (a stalled browser, a sleeping laptop) is dropped; its browser reconnects and gets the
latest state first, so one slow page can never hold the others or the bus.
"""

from __future__ import annotations

import json
import logging
import queue
import re
import threading
import time
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, ValidationError

from runtime.messaging.bus import Bus
from runtime.messaging.messages import (
    MAX_NAME,
    MAX_TEXT,
    Command,
    Confirm,
    EStop,
    Event,
    Heartbeat,
    JointStateMsg,
    PlanSummary,
    Status,
    describe_errors,
)

log = logging.getLogger(__name__)

JOINT_STATE_PAGE_HZ = 10.0
PAGE_QUEUE_EVENTS = 256  # a page this many events behind is dropped (it reconnects and gets the latest state)
MAX_IMAGE_BYTES = 8 * 1024 * 1024
MAX_IMAGES = 32
IMAGE_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")


class ActionRefused(ValueError):
    """An operator action whose body is not what the action takes; str() says what is wrong."""


class _Body(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class RunBody(_Body):
    instruction: Annotated[str, StringConstraints(strip_whitespace=True, min_length=1, max_length=MAX_TEXT)]


class ConfirmBody(_Body):
    plan_id: str = Field(min_length=1, max_length=MAX_NAME)
    approve: bool = True


class NoBody(_Body):
    pass


BODIES: dict[str, type[_Body]] = {"run": RunBody, "confirm": ConfirmBody, "abort": NoBody, "reset": NoBody}
ACTIONS = frozenset({"estop", *BODIES})


class PageStream:
    """One page's server-sent events, oldest first, bounded."""

    def __init__(self) -> None:
        self.events: queue.Queue[bytes] = queue.Queue(maxsize=PAGE_QUEUE_EVENTS)
        self.dropped = threading.Event()

    def offer(self, frame: bytes) -> None:
        try:
            self.events.put_nowait(frame)
        except queue.Full:
            self.dropped.set()


def sse_frame(kind: str, data: dict) -> bytes:
    return f"data: {json.dumps({'type': kind, 'data': data})}\n\n".encode()


class Bridge:
    def __init__(self, bus: Bus, node: str = "console") -> None:
        self.bus, self.node = bus, node
        self._lock = threading.Lock()
        self._pages: list[PageStream] = []
        self.latest: dict[str, bytes] = {}  # kind -> its latest encoded event, for pages that join later
        self.images: dict[str, tuple[int, bytes]] = {}
        self._last_joint_push = 0.0
        self._seq = 0
        self.closed = threading.Event()
        keys = bus.keys
        bus.subscribe(keys.status, Status, lambda k, m: self._push("status", m.model_dump()))
        bus.subscribe(keys.events, Event, lambda k, m: self._push("event", m.model_dump(), keep=False))
        bus.subscribe(keys.plan, PlanSummary, lambda k, m: self._push("plan", m.model_dump()))
        bus.subscribe(keys.joint_state, JointStateMsg, self._on_joint_state)
        bus.subscribe_bytes(f"{keys.images}/*", self._on_image, max_bytes=MAX_IMAGE_BYTES)
        threading.Thread(target=self._heartbeat, name="console-heartbeat", daemon=True).start()

    # -- downstream: bus -> pages ---------------------------------------------------------------------------
    def _push(self, kind: str, data: dict, keep: bool = True) -> None:
        frame = sse_frame(kind, data)
        with self._lock:
            if keep:
                self.latest[kind] = frame
            pages = tuple(self._pages)
        for page in pages:
            page.offer(frame)

    def _on_joint_state(self, _key: str, msg: JointStateMsg) -> None:
        now = time.monotonic()
        if now - self._last_joint_push >= 1.0 / JOINT_STATE_PAGE_HZ:
            self._last_joint_push = now
            self._push("joint_state", msg.model_dump())

    def _on_image(self, key: str, payload: bytes) -> None:
        pattern = f"{self.bus.keys.images}/*"
        name = key.rsplit("/", 1)[-1]
        if not IMAGE_NAME.fullmatch(name):
            self.bus.refuse(pattern, key, "image name must be 1-32 lower-case letters, digits or _")
            return
        with self._lock:
            if name not in self.images and len(self.images) >= MAX_IMAGES:
                full = True
            else:
                full = False
                version = self.images.get(name, (0, b""))[0] + 1
                self.images[name] = (version, payload)
        if full:
            self.bus.refuse(pattern, key, f"more than {MAX_IMAGES} image names")
            return
        self._push("image", {"name": name, "version": version}, keep=False)

    def attach(self) -> PageStream:
        """A new page's stream, starting with the latest status, plan, joints and images."""
        page = PageStream()
        with self._lock:
            self._pages.append(page)
            for frame in self.latest.values():
                page.offer(frame)
            for name, (version, _) in self.images.items():
                page.offer(sse_frame("image", {"name": name, "version": version}))
        return page

    def page_count(self) -> int:
        with self._lock:
            return len(self._pages)

    def detach(self, page: PageStream) -> None:
        with self._lock:
            if page in self._pages:
                self._pages.remove(page)

    def _heartbeat(self) -> None:
        """The console's own presence (kind console: shown to operators, not a deadman for execution)."""
        key = self.bus.keys.heartbeat_of(self.node)
        while not self.closed.wait(0.5):
            self._seq += 1
            self.bus.publish(key, Heartbeat(stamp_s=time.time(), node=self.node, kind="console", seq=self._seq))

    def close(self) -> None:
        self.closed.set()

    # -- upstream: operator actions -> bus --------------------------------------------------------------------
    def estop(self) -> None:
        self.bus.publish(
            self.bus.keys.estop, EStop(stamp_s=time.time(), source=self.node, reason="console E-STOP button")
        )

    def act(self, action: str, body: dict) -> None:
        """Publish a checked operator action (not estop: that one never waits for a body)."""
        try:
            checked = BODIES[action].model_validate(body)
        except ValidationError as e:
            raise ActionRefused(f"{action}: {describe_errors(e)}") from None
        keys, now = self.bus.keys, time.time()
        if isinstance(checked, ConfirmBody):
            message = Confirm(stamp_s=now, plan_id=checked.plan_id, source=self.node, approve=checked.approve)
            self.bus.publish(keys.confirm, message)
            return
        instruction = checked.instruction if isinstance(checked, RunBody) else ""
        self.bus.publish(keys.command, Command(stamp_s=now, action=action, instruction=instruction, source=self.node))
