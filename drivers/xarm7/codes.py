"""SDK return codes -> the typed driver errors, with the controller's own error code looked up when it has one.

Every XArmAPI call returns an API code (0 = done). Code 1 means the controller holds an error: the call is
refused until `clear_fault()`, so the controller's error code is read and raised as ControllerError. Warnings
(code 2) do not stop motion; they are logged and cleared.
"""

from __future__ import annotations

import logging
from typing import Any

from drivers.errors import ApiError, ArmStoppedError, ControllerError, NotConnectedError

log = logging.getLogger(__name__)

CONTROLLER_WARNINGS: dict[int, str] = {11: "command cache full (set-points sent faster than executed)"}
RECOVER_HINT = "release the e-stop / remove the cause, then clear_fault()"


def controller_codes(api: Any) -> tuple[int, int]:
    """(error, warning) codes held by the controller; asks over TCP, falls back to the 100 Hz report."""
    try:
        code, pair = api.get_err_warn_code()
        if code == 0:
            return int(pair[0]), int(pair[1])
    except Exception as e:  # the connection may be gone: the report still holds the last codes
        log.debug("get_err_warn_code failed: %s", e)
    return int(getattr(api, "error_code", 0) or 0), int(getattr(api, "warn_code", 0) or 0)


def check(api: Any, call: str, result: Any) -> Any:
    """Raise the driver error for a call's API code; return the payload of `(code, value)` results."""
    if isinstance(result, tuple | list):  # (code, value), or [code] (the SDK's set_fence_mode returns its raw reply)
        code, value = result[0], (result[1] if len(result) > 1 else None)
    else:
        code, value = result, None
    if code == 0 or code is None:
        return value
    if code == 2:
        _, warn = controller_codes(api)
        log.warning("%s: controller warning %d: %s", call, warn, CONTROLLER_WARNINGS.get(warn, "see the xArm manual"))
        api.clean_warn()
        return value
    if code == 1:
        error, _ = controller_codes(api)
        raise ControllerError(error, f"{call} refused; {RECOVER_HINT}")
    if code == -9:
        raise ArmStoppedError(f"{call}: the arm is in its emergency-stop state (API code -9); {RECOVER_HINT}")
    if code == -1:
        raise NotConnectedError(f"{call}: the xArm controller is not connected (API code -1): check the Ethernet link")
    raise ApiError(call, int(code))
