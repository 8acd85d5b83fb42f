"""An xArm 7 controller on loopback that the real xarm-python-sdk connects to, over the MuJoCo twin.

    with XArmEmulator(world) as emulator:          # listens on a free 127.0.0.N, ports 502 and 30003
        arm = XArm7(RobotConfig(kind="xarm7", ip=emulator.address), safety)

Faults are switched through `emulator.faults` (stalls, corrupt replies, a silent report, any action after the n-th
set-point) and the methods here (drop a connection, refuse new ones, a controller error, the e-stop button).
"""

from __future__ import annotations

from types import TracebackType
from typing import Self

from drivers.sim.world import SimWorld
from drivers.xarm7.emulator.controller import ControllerModel, Journal
from drivers.xarm7.emulator.faults import Faults
from drivers.xarm7.emulator.server import REPORT_HZ, ControllerServer, real_time


class XArmEmulator:
    """Owns the controller model and its TCP services; the world (and its physics thread) stays the caller's."""

    def __init__(
        self,
        world: SimWorld,
        address: str | None = None,
        control_rate_hz: float = 100.0,
        report_hz: float = REPORT_HZ,
    ) -> None:
        self.world = world
        self.model = ControllerModel(world, control_rate_hz)
        self.faults = Faults()
        self._address, self._report_hz = address, report_hz
        self.server: ControllerServer | None = None  # kept after stop() for what it served
        self._running = False

    @property
    def address(self) -> str:
        if self.server is None:
            raise RuntimeError("XArmEmulator.address before start()")
        return self.server.address

    @property
    def running(self) -> bool:
        return self._running

    @property
    def journal(self) -> Journal:
        return self.model.journal

    def start(self) -> Self:
        """Bind both ports (EmulatorBindError if taken), power the controller on, serve."""
        if self._running:
            return self
        if self.server is not None:
            raise RuntimeError("an XArmEmulator starts once; make a new one")
        self.server = ControllerServer(self.model, self.faults, self._address, self._report_hz)
        self.model.connect()
        if self.world.physics_thread_id is not None:
            real_time(self.world.physics_thread_id)  # the twin stands for the robot: it keeps time like one
        self.server.start()
        self._running = True
        return self

    def stop(self) -> None:
        """Close every connection and both ports (idempotent)."""
        if self._running:
            self._running = False
            self.server.stop()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    # -- link and controller faults -----------------------------------------------------------------------
    def _server(self) -> ControllerServer:
        if not self._running:
            raise RuntimeError("the emulator is not running")
        return self.server

    def drop_command_link(self) -> None:
        self._server().drop_command_link()

    def drop_report_link(self) -> None:
        self._server().drop_report_link()

    def refuse_connections(self) -> None:
        self._server().refuse_connections()

    def accept_connections(self) -> None:
        self._server().accept_connections()

    def error_after(self, setpoints: int, code: int = 31) -> None:
        """The controller raises error `code` right after executing the n-th set-point from now."""
        self.faults.after_setpoints(
            setpoints, lambda: self.model.trip(code, "injected mid-trajectory"), f"controller error {code}"
        )

    def press_estop_button(self) -> None:
        self.model.press_estop_button()
        self.faults.fire("e-stop button")

    def release_estop_button(self) -> None:
        self.model.release_estop_button()
