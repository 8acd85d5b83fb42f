"""Typed driver errors with messages a person can act on.

Controller error and API codes follow the xArm SDK (see README, hardware section); the simulated arm raises the
same codes so the layers above handle one vocabulary.
"""

from __future__ import annotations


class DriverError(RuntimeError):
    """Root of every driver failure."""


class NotConnectedError(DriverError):
    """A method that needs a connection was called before connect() or after close()."""


class DeviceNotFoundError(DriverError):
    """The device is not reachable (no camera on USB, no arm at the configured address)."""


class CameraTimeoutError(DriverError):
    """No new frame arrived within the read timeout."""


class StaleFrameError(DriverError):
    """The newest frame is older than the allowed age."""


class ArmStoppedError(DriverError):
    """The arm was stopped (stop() or e-stop); clear_fault() re-enables servo mode."""


# Controller error codes (xArm controller, get_err_warn_code) -> readable text.
CONTROLLER_ERRORS: dict[int, str] = {
    1: "emergency stop button pressed",
    2: "emergency stop IO triggered",
    3: "three-state switch released",
    10: "servo fault",
    11: "servo fault (joint 1)",
    12: "servo fault (joint 2)",
    13: "servo fault (joint 3)",
    14: "servo fault (joint 4)",
    15: "servo fault (joint 5)",
    16: "servo fault (joint 6)",
    17: "servo fault (joint 7)",
    22: "self-collision detected",
    23: "joint angle exceeds limit",
    24: "speed exceeds limit",
    25: "planning error",
    31: "collision detected (abnormal joint current)",
    35: "safety boundary (TCP fence) violated",
    40: "inverse kinematics failure",
}

# SDK API return codes -> readable text.
API_CODES: dict[int, str] = {
    -9: "emergency stop state",
    -8: "out of range",
    -7: "joint angle limit",
    -6: "cartesian position limit",
    -2: "robot not ready",
    -1: "not connected",
    1: "uncleared controller error",
    2: "uncleared controller warning",
    3: "reply timeout",
    4: "reply of the wrong length",
    5: "reply to another request",
    6: "reply with the wrong protocol id (malformed)",
    7: "reply to another command",
    8: "send error",
    9: "state not ready",
    10: "command invalid or failed",
    11: "other error",
    12: "parameter error",
}


class ControllerError(DriverError):
    """The arm controller reported an error and stopped; clear_fault() is needed before motion."""

    def __init__(self, code: int, detail: str = "") -> None:
        self.code = code
        self.detail = detail
        text = CONTROLLER_ERRORS.get(code, "unknown controller error")
        super().__init__(f"controller error {code}: {text}" + (f" ({detail})" if detail else ""))


class ApiError(DriverError):
    """An SDK call returned a non-zero API code."""

    def __init__(self, call: str, code: int) -> None:
        self.call = call
        self.code = code
        super().__init__(f"{call} returned API code {code}: {API_CODES.get(code, 'unknown code')}")
