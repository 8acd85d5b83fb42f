"""What the manipulation phases read of a contact decision.

pipeline.contact.ContactPlan is the one type that carries it from contact planning to execution; motion does
not import the pipeline (the two share a layer), so this states the fields it relies on. The joints are the ones
contact planning solved in the gate's scene: the phases plan from them and check them, they do not solve again
(but for the pre-contact joints where the line down from them is not free and the line up from the contact's own
joints is: ManipulationChain.descent).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from safety.geometry import Primitive


class Contact(Protocol):
    @property
    def mode(self) -> str: ...  # "grasp" | "push" | "hinge"

    @property
    def T_pre(self) -> np.ndarray: ...  # approach start, TCP in the base frame

    @property
    def T_contact(self) -> np.ndarray: ...  # grasp pose, or where the push starts

    @property
    def T_goal(self) -> np.ndarray: ...  # grasp: the goal pose the object is set down above; push: its end

    @property
    def T_motion(self) -> np.ndarray: ...  # the object's motion (x_goal = T x_init, base frame)

    @property
    def width_m(self) -> float: ...  # finger gap to command at contact

    @property
    def open_width_m(self) -> float: ...  # finger gap on the approach and down to the contact

    @property
    def release_width_m(self) -> float: ...  # grasp: finger gap opened to let go (at least open_width_m)

    @property
    def q_pre(self) -> np.ndarray: ...  # joints at T_pre

    @property
    def q_contact(self) -> np.ndarray: ...  # joints at T_contact

    @property
    def via(self) -> tuple[np.ndarray, ...]: ...  # TCP poses a push passes between contact and goal

    @property
    def T_place(self) -> tuple[np.ndarray, ...]: ...  # grasp: release pose, then the pose above it

    @property
    def q_place(self) -> tuple[np.ndarray, ...]: ...  # their joints

    @property
    def held(self) -> Primitive | None: ...  # grasp: the object in the TCP frame once grasped

    @property
    def source(self) -> str: ...  # who decided, for the record
