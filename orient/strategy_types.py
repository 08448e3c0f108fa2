"""The types behind the decision rules (:mod:`orient.strategies`).

Operator input, the posture state a rule sees, the change it proposes, the
protocols of the posture model and of a rule, and the candidate grid of the
analytical rules. Angles in radians; lead/tilt as in ``orient/geometry.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from orient.detect import Detection
from orient.memory import CuttingConditions, _real
from orient.constants import DEFAULT_GRID_HALF_WIDTH_RAD, DEFAULT_GRID_STEP_RAD, ROUND_SLACK

__all__ = [
    "DEFAULT_GRID_HALF_WIDTH_RAD",
    "DEFAULT_GRID_STEP_RAD",
    "OperatorInput",
    "PostureChange",
    "PostureGrid",
    "PostureModel",
    "PostureState",
    "Strategy",
]



# --- data ------------------------------------------------------------------------
@dataclass(frozen=True)
class OperatorInput:
    """What the operator says about a chatter (patent [0063], [0100]).

    Parameters
    ----------
    cause : {'A', 'B', 'C'}
        A: the tool side (end mill), B: the workpiece side, C: unknown.
    """

    cause: str

    def __post_init__(self) -> None:
        if self.cause not in ("A", "B", "C"):
            raise ValueError(f"cause: expected 'A', 'B' or 'C', got {self.cause!r}")


@dataclass(frozen=True)
class PostureState:
    """The current posture at a cutter location.

    Parameters
    ----------
    lead_rad, tilt_rad : float [rad]
    inclination_rad : float [rad]
        Angle between tool axis and surface normal, in [0, pi].
    cut_sense : float [-]
        Up/down-cut degree in [-1, 1], positive up-cut.
    spindle_rpm : float [rev/min]
    conditions : CuttingConditions or None
        Context for :class:`MemoryRule`.
    context : dict
        Anything else the caller wants to carry (not compared).
    """

    lead_rad: float
    tilt_rad: float
    inclination_rad: float
    cut_sense: float
    spindle_rpm: float
    conditions: CuttingConditions | None = None
    context: dict = field(default_factory=dict, compare=False, hash=False)

    def __post_init__(self) -> None:
        _real("lead_rad", self.lead_rad)
        _real("tilt_rad", self.tilt_rad)
        inc = _real("inclination_rad", self.inclination_rad, ">=0")
        if inc > math.pi:
            raise ValueError(f"inclination_rad: expected a value in [0, pi], got {inc!r}")
        cs = _real("cut_sense", self.cut_sense)
        if abs(cs) > 1.0:
            raise ValueError(f"cut_sense: expected a value in [-1, 1], got {cs!r}")
        _real("spindle_rpm", self.spindle_rpm, ">0")
        if self.conditions is not None and not isinstance(self.conditions, CuttingConditions):
            raise TypeError("conditions: expected CuttingConditions or None, "
                            f"got {type(self.conditions).__name__}")

    @classmethod
    def from_model(cls, model: PostureModel, lead_rad: float, tilt_rad: float,
                   spindle_rpm: float, conditions: CuttingConditions | None = None,
                   **context: Any) -> PostureState:
        """State whose inclination and cut sense come from ``model``."""
        return cls(lead_rad, tilt_rad, float(model.inclination(lead_rad, tilt_rad)),
                   float(model.cut_sense(lead_rad, tilt_rad)), spindle_rpm, conditions,
                   dict(context))


@dataclass(frozen=True)
class PostureChange:
    """A proposed posture: new lead and tilt [rad] and why."""

    lead_rad: float
    tilt_rad: float
    reason: str


@runtime_checkable
class PostureModel(Protocol):
    """What the rules need to know about postures at one cutter location.

    The planner provides the real implementation (geometry, process gain,
    stability analysis, interference check); the rules never compute physics.
    """

    def inclination(self, lead: float, tilt: float) -> float:
        """Angle between tool axis and surface normal [rad]."""

    def cut_sense(self, lead: float, tilt: float) -> float:
        """Up/down-cut degree in [-1, 1], positive up-cut [-]."""

    def margin(self, lead: float, tilt: float) -> float:
        """Stability margin (> 1 stable) [-]."""

    def gain(self, lead: float, tilt: float, direction: np.ndarray) -> float:
        """Scalar process gain ``e^T P e`` along a unit direction e [N/m]."""

    def feasible(self, lead: float, tilt: float) -> bool:
        """No interference, within the axis limits."""


@runtime_checkable
class Strategy(Protocol):
    """A decision rule: a posture change for a state and an event, or None."""

    last_reason: str

    def propose(self, state: PostureState, event: OperatorInput | Detection | None
                ) -> PostureChange | None:
        """The posture to go to, or None (see ``last_reason``)."""


@dataclass(frozen=True)
class PostureGrid:
    """Candidate postures: a square grid around the current one.

    Parameters
    ----------
    half_width_rad : float [rad]
        Lead and tilt within +- this of the current posture.
    step_rad : float [rad]
        Grid spacing.
    """

    half_width_rad: float = DEFAULT_GRID_HALF_WIDTH_RAD
    step_rad: float = DEFAULT_GRID_STEP_RAD

    def __post_init__(self) -> None:
        _real("half_width_rad", self.half_width_rad, ">=0")
        _real("step_rad", self.step_rad, ">0")

    def around(self, lead_rad: float, tilt_rad: float) -> np.ndarray:
        """Candidates, shape (m, 2) [rad] (lead, tilt); the current posture included."""
        n = math.floor(self.half_width_rad / self.step_rad + ROUND_SLACK)
        off = np.arange(-n, n + 1) * self.step_rad
        dl, dt = np.meshgrid(off, off, indexing="ij")
        return np.column_stack([lead_rad + dl.ravel(), tilt_rad + dt.ravel()])


