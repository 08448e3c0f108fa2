"""The patent's decision rules for the tool posture, behind one interface.

JP2010-260120 (Nagoya) changes the angle between a ball end mill and the
workpiece when chatter occurs or threatens. Each rule here is one of its
embodiments; all share the :class:`Strategy` protocol::

    change = strategy.propose(state, event)     # PostureChange or None
    strategy.last_reason                        # why (also when None)

``state`` is the current :class:`PostureState`; ``event`` an
:class:`OperatorInput` (cause A tool / B workpiece / C unknown), a
:class:`~orient.detect.Detection` from the chatter detector, or None (nothing
new). Rules do no physics: everything that depends on the geometry and the
process comes from a :class:`PostureModel` (inclination, up/down-cut degree,
process gain along a direction, stability margin, feasibility = interference
and axis limits), given to the constructor and replaceable per call
(``propose(..., model=...)``, as the model belongs to a cutter location). Every
proposal has passed ``model.feasible``; when no candidate is feasible the rule
returns None and says so in ``last_reason`` (patent [0071], S150: the target
angle is limited to the non-interfering range).

Angles in radians; lead/tilt as in ``orient/geometry.py``; ``cut_sense`` in
[-1, 1], positive up-cut. Local moves of a rule are searched on rings of
``RING_DIRECTIONS`` directions around a posture, with radii ``step * f`` for
``f`` in ``STEP_FRACTIONS`` (the largest feasible step wins when it is best).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

from orient.detect import Detection
from orient.memory import PostureMemory, _real
from orient.strategy_types import (
    OperatorInput,
    PostureChange,
    PostureGrid,
    PostureModel,
    PostureState,
    Strategy,
)
from orient.constants import (
    CHANGE_TOL,
    DEFAULT_MEMORY_MAX_DISTANCE,
    DEFAULT_STEP_RAD,
    LEARN_DEDUPE_DISTANCE,
    LEARN_DEDUPE_K,
    MIN_REL_IMPROVEMENT,
    RING_DIRECTIONS,
    SAME_POSTURE_RAD,
    STEP_FRACTIONS,
)

__all__ = ["DEFAULT_STEP_RAD", "DetectorRule", "EigenCriterion", "GainMinimization",
           "MemoryRule", "OperatorInput", "OperatorRule", "PostureChange", "PostureGrid",
           "PostureModel", "PostureState", "Strategy", "TrialRule"]



# --- helpers ---------------------------------------------------------------------
def _is_chatter(event: Any) -> bool | None:
    """True/False for a chatter report, None for no news; TypeError otherwise."""
    if event is None:
        return None
    if isinstance(event, OperatorInput):
        return True
    if isinstance(event, Detection):
        return bool(event.chatter)
    raise TypeError(f"event: expected OperatorInput, Detection or None, "
                    f"got {type(event).__name__}")


def _ring(lead: float, tilt: float, step: float) -> np.ndarray:
    """Moves around (lead, tilt): shape (len(STEP_FRACTIONS) * RING_DIRECTIONS, 2) [rad]."""
    ang = np.arange(RING_DIRECTIONS) * (2.0 * math.pi / RING_DIRECTIONS)
    radii = step * np.asarray(STEP_FRACTIONS)
    dl = np.outer(radii, np.cos(ang)).ravel()
    dt = np.outer(radii, np.sin(ang)).ravel()
    return np.column_stack([lead + dl, tilt + dt])


def _same(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return abs(a[0] - b[0]) <= SAME_POSTURE_RAD and abs(a[1] - b[1]) <= SAME_POSTURE_RAD


def _deg(x: float) -> str:
    return f"{math.degrees(x):.1f} deg"


class _Rule:
    """Common parts: the model, the step, ``last_reason``."""

    def __init__(self, model: PostureModel, step_rad: float = DEFAULT_STEP_RAD) -> None:
        if not isinstance(model, PostureModel):
            raise TypeError(f"model: expected a PostureModel, got {type(model).__name__}")
        self.model = model
        self.step_rad = _real("step_rad", step_rad, ">0")
        self.last_reason = ""

    def _model(self, model: PostureModel | None) -> PostureModel:
        if model is None:
            return self.model
        if not isinstance(model, PostureModel):
            raise TypeError(f"model: expected a PostureModel, got {type(model).__name__}")
        return model

    def _none(self, reason: str) -> None:
        self.last_reason = reason

    def _change(self, lead: float, tilt: float, reason: str) -> PostureChange:
        self.last_reason = reason
        return PostureChange(float(lead), float(tilt), reason)


# --- trial (5th embodiment) --------------------------------------------------------
class TrialRule(_Rule):
    """Try one way by a step; if chatter persists, go the other way.

    Fifth embodiment ([0091]-[0094], item (16), Fig. 13) and [0116] (operator
    cause C on the CAM side). The patent's adjustable angle is about the feed
    direction, i.e. the tilt here. On a chatter report in the idle state the
    tilt changes by ``step_rad`` in the direction that increases the
    inclination (``first='incline'``, the patent's S520) or decreases it
    (``first='upright'``, its alternative). The next report decides:

    * no chatter (a Detection with ``chatter=False``): keep the tried posture
      (S540), back to idle;
    * chatter persists (a Detection with chatter or another OperatorInput):
      go the other way, two steps back from the tried tilt, i.e. one step on
      the other side of the original (S550);
    * chatter still persists after the reversal: give up (None) until a report
      without chatter, :meth:`reset`, or the posture being changed by someone
      else (the trial's bookkeeping is dropped when the state's posture is
      not the one it proposed).

    If the first way is infeasible it goes the other way at once; ``event=None``
    (no news) changes nothing. ``settle_detections`` Detection events after
    each change are ignored (their windows may still hold the old vibration).

    Parameters
    ----------
    model : PostureModel
    step_rad : float [rad]
    first : {'incline', 'upright'}
    settle_detections : int
    """

    def __init__(self, model: PostureModel, step_rad: float = DEFAULT_STEP_RAD,
                 first: str = "incline", settle_detections: int = 0) -> None:
        super().__init__(model, step_rad)
        if first not in ("incline", "upright"):
            raise ValueError(f"first: expected 'incline' or 'upright', got {first!r}")
        if (isinstance(settle_detections, bool) or not isinstance(settle_detections,
                                                                   numbers.Integral)
                or settle_detections < 0):
            raise ValueError(f"settle_detections: expected an integer >= 0, "
                             f"got {settle_detections!r}")
        self.first = first
        self.settle_detections = int(settle_detections)
        self.reset()

    def reset(self) -> None:
        """Forget any trial in progress."""
        self.phase = "idle"      # idle | trying | reversed | exhausted
        self._set: tuple[float, float] | None = None   # posture we proposed last
        self._sign = 0.0
        self._settle = 0

    def propose(self, state: PostureState, event: OperatorInput | Detection | None, *,
                model: PostureModel | None = None) -> PostureChange | None:
        """See the class docstring."""
        m = self._model(model)
        chatter = _is_chatter(event)
        here = (state.lead_rad, state.tilt_rad)
        if self.phase != "idle" and (self._set is None or not _same(here, self._set)):
            self.reset()
        if chatter is None:
            return self._none(f"no event (trial phase: {self.phase})")
        if isinstance(event, Detection) and self._settle > 0:
            self._settle -= 1
            return self._none("settling after the last posture change")
        if not chatter:
            done = {"trying": "trial succeeded: chatter stopped, keeping the tried posture",
                    "reversed": "reversal succeeded: chatter stopped, keeping the posture",
                    "exhausted": "chatter stopped"}.get(self.phase, "no chatter")
            self.reset()
            return self._none(done)
        lead, tilt = here
        if self.phase == "idle":
            up = m.inclination(lead, tilt + self.step_rad)
            down = m.inclination(lead, tilt - self.step_rad)
            s = 1.0 if up >= down else -1.0
            if self.first == "upright":
                s = -s
            step = _deg(self.step_rad)
            for phase, sign, why in (
                    ("trying", s, f"trial: tilt {self.first}s by {step}"),
                    ("reversed", -s, f"trial: first way infeasible, tilt the other way by {step}")):
                target = (lead, tilt + sign * self.step_rad)
                if m.feasible(*target):
                    self.phase, self._sign, self._set = phase, s, target
                    self._settle = self.settle_detections
                    return self._change(*target, why)
            return self._none("trial: neither tilt direction is feasible")
        if self.phase == "trying":
            target = (lead, tilt - 2.0 * self._sign * self.step_rad)
            if m.feasible(*target):
                self.phase, self._set = "reversed", target
                self._settle = self.settle_detections
                return self._change(*target, "trial: chatter persisted, tilt the other way "
                                    f"({_deg(2 * self.step_rad)} back)")
            self.phase = "exhausted"
            return self._none("trial: chatter persisted and the other way is infeasible")
        self.phase = "exhausted"
        return self._none("trial: chatter persists both ways; waiting for reset() or "
                          "a report without chatter")


# --- cause rules (1st-3rd and 7th embodiments) ----------------------------------------
class _CauseRule(_Rule):
    """Tool side: decrease the inclination; workpiece side: increase it, up-cut."""

    def __init__(self, model: PostureModel, step_rad: float = DEFAULT_STEP_RAD,
                 trial: TrialRule | None = None) -> None:
        super().__init__(model, step_rad)
        self.trial = TrialRule(model, step_rad) if trial is None else trial
        if not isinstance(self.trial, TrialRule):
            raise TypeError(f"trial: expected TrialRule, got {type(trial).__name__}")

    def _decide(self, state: PostureState, cause: str, event: Any,
                m: PostureModel) -> PostureChange | None:
        if cause == "A":
            return self._tool_side(state, m)
        if cause == "B":
            return self._workpiece_side(state, m)
        change = self.trial.propose(state, event, model=m)
        self.last_reason = "cause unknown, " + self.trial.last_reason
        return change

    def _evaluate(self, cand: np.ndarray, m: PostureModel
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ok = np.array([bool(m.feasible(lt, tt)) for lt, tt in cand], dtype=bool)
        cand = cand[ok]
        inc = np.array([m.inclination(lt, tt) for lt, tt in cand], dtype=float)
        cs = np.array([m.cut_sense(lt, tt) for lt, tt in cand], dtype=float)
        return cand, inc, cs

    def _tool_side(self, s: PostureState, m: PostureModel) -> PostureChange | None:
        cand, inc, _ = self._evaluate(_ring(s.lead_rad, s.tilt_rad, self.step_rad), m)
        if cand.size == 0:
            return self._none("tool side: no feasible posture within a step")
        i = int(np.argmin(inc))
        if inc[i] >= s.inclination_rad - CHANGE_TOL:
            return self._none("tool side: the inclination cannot be decreased further "
                              "(at its minimum or blocked)")
        return self._change(*cand[i], f"tool side: inclination {_deg(s.inclination_rad)} -> "
                            f"{_deg(inc[i])}")

    def _workpiece_side(self, s: PostureState, m: PostureModel) -> PostureChange | None:
        lead, tilt, inc0, cs0 = s.lead_rad, s.tilt_rad, s.inclination_rad, s.cut_sense
        ring = self._evaluate(_ring(lead, tilt, self.step_rad), m)
        higher = ring[1] > inc0 + CHANGE_TOL
        # (candidates, inclinations, cut senses, allowed, inclination first?, note), in order
        options = []
        if cs0 <= 0.0:   # down-cut (or neutral): the up-cut side, mirroring tilt and/or lead
            mirrors = [p for p in ((lead, -tilt), (-lead, tilt), (-lead, -tilt))
                       if not _same(p, (lead, tilt))]
            if mirrors:
                c, i, k = self._evaluate(np.vstack([np.array(mirrors)] + [
                    _ring(ml, mt, self.step_rad) for ml, mt in mirrors]), m)
                options.append((c, i, k, k > CHANGE_TOL, True, "down-cut -> up-cut"))
        else:            # up-cut: its degree grows with the inclination, or at least stays up
            options.append((*ring, higher & (ring[2] > cs0 + CHANGE_TOL), True,
                            "up-cut degree grows"))
            options.append((*ring, higher & (ring[2] > 0.0), False,
                            "still up-cut, its degree cannot grow"))
        options.append((*ring, higher, True,
                        "no feasible up-cut posture with a larger inclination"))
        for c, i, k, allowed, inclination_first, note in options:
            if np.any(allowed):
                idx = np.flatnonzero(allowed)
                keys = (-k[idx], -i[idx]) if inclination_first else (-i[idx], -k[idx])
                j = int(idx[np.lexsort(keys)[0]])
                return self._change(*c[j], f"workpiece side: inclination {_deg(inc0)} -> "
                                    f"{_deg(i[j])}, {note} (cut sense {cs0:+.2f} -> "
                                    f"{k[j]:+.2f})")
        return self._none("workpiece side: the inclination cannot be increased (blocked)")


class OperatorRule(_CauseRule):
    """The operator names the cause; the rule sets the posture.

    First embodiment ([0062]-[0074], claims 3-4, Fig. 4), with the up/down-cut
    refinement of the third ([0081]-[0085], claim 6, Fig. 10) and cause C of the
    seventh ([0100]-[0103], [0116]):

    * A, tool side: decrease the inclination between tool axis and surface
      normal by up to ``step_rad`` (the force turns toward the stiff axis,
      [0069]; S140);
    * B, workpiece side: increase the inclination ([0066], S130) and prefer
      up-cut ([0083]-[0085]): from down-cut, switch to the up-cut side by
      mirroring tilt and/or lead (Fig. 5: 30 -> 150 deg, 70 -> 110 deg; S350),
      pushed one step further out where feasible; already up-cut, increase the
      inclination so that the up-cut degree grows (S360); falls back to a
      plain increase of the inclination when no up-cut posture is feasible;
    * C, unknown: a trial (:class:`TrialRule`, own state, same step).

    Only :class:`OperatorInput` events act; Detections and None change nothing.

    Parameters
    ----------
    model : PostureModel
    step_rad : float [rad]
    trial : TrialRule or None
        The trial used for cause C (default: a new one with the same step).
    """

    def propose(self, state: PostureState, event: OperatorInput | Detection | None, *,
                model: PostureModel | None = None) -> PostureChange | None:
        """See the class docstring."""
        m = self._model(model)
        _is_chatter(event)
        if not isinstance(event, OperatorInput):
            return self._none("no operator input")
        return self._decide(state, event.cause, event, m)


class DetectorRule(_CauseRule):
    """The detector names the cause; the same decisions as :class:`OperatorRule`.

    Second embodiment ([0075]-[0080], claim 5, Fig. 8) with the third's up-cut
    preference: detector cause ``'tool'`` -> A, ``'workpiece'`` -> B, None
    (chatter of unknown side) -> C (trial). Only Detections with ``chatter=True``
    act; a Detection without chatter is passed to the trial (it ends one).

    Parameters
    ----------
    model : PostureModel
    step_rad : float [rad]
    trial : TrialRule or None
    """

    def propose(self, state: PostureState, event: OperatorInput | Detection | None, *,
                model: PostureModel | None = None) -> PostureChange | None:
        """See the class docstring."""
        m = self._model(model)
        _is_chatter(event)
        if not isinstance(event, Detection):
            return self._none("no detection")
        if not event.chatter:
            self.trial.propose(state, event, model=m)
            return self._none("no chatter detected")
        cause = {"tool": "A", "workpiece": "B"}.get(event.cause, "C")
        return self._decide(state, cause, event, m)


# --- analytical rules (4th embodiment) --------------------------------------------------
class _GridRule(_Rule):
    def __init__(self, model: PostureModel, candidates: PostureGrid | None = None,
                 always: bool = False) -> None:
        super().__init__(model)
        self.candidates = PostureGrid() if candidates is None else candidates
        if not isinstance(self.candidates, PostureGrid):
            raise TypeError(f"candidates: expected PostureGrid, got {type(candidates).__name__}")
        self.always = bool(always)

    def _search(self, state: PostureState, event: Any, m: PostureModel, score: Any,
                what: str) -> PostureChange | None:
        """Minimize ``score(lead, tilt)`` over the feasible candidates."""
        chatter = _is_chatter(event)
        if not (chatter or self.always):
            return self._none("no chatter reported")
        cand = self.candidates.around(state.lead_rad, state.tilt_rad)
        ok = np.array([bool(m.feasible(lt, tt)) for lt, tt in cand], dtype=bool)
        if not np.any(ok):
            return self._none(f"{what}: no feasible candidate posture")
        cand = cand[ok]
        val = np.array([score(lt, tt) for lt, tt in cand], dtype=float)
        i = int(np.argmin(val))
        here = score(state.lead_rad, state.tilt_rad)
        if val[i] >= here - MIN_REL_IMPROVEMENT * abs(here):
            return self._none(f"{what}: the current posture is already the best candidate")
        return self._change(*cand[i], f"{what}: {abs(here):.4g} -> {abs(val[i]):.4g} at lead "
                            f"{_deg(cand[i][0])}, tilt {_deg(cand[i][1])}")


class GainMinimization(_GridRule):
    """Posture of the smallest average process gain along the chatter direction.

    Fourth embodiment, one direction ([0086]-[0089], item (15), Fig. 12, eq. (1)):
    ``P_xx = f_x,av / x``, the revolution-averaged force increase per unit
    displacement along the (known) chatter direction, is made small. The
    quantity minimized is ``|e^T P e|`` (``model.gain``): with the contract's
    sign convention P is "negative" (a chip-thickness increase pushes the tool
    back), so ``e^T P e`` is mostly negative and its *magnitude* is the
    patent's gain; in the one-direction zero-order limit the critical scaling
    is ``-1 / (2 p min Re g)`` for ``p < 0`` and ``1 / (2 p max Re g)`` for
    ``p > 0``, inversely proportional to ``|p|`` either way.

    Acts on chatter reports (any OperatorInput, Detections with chatter), or
    always with ``always=True`` (CAM-side planning).

    Parameters
    ----------
    model : PostureModel
    direction : array_like, shape (3,) [-]
        Chatter direction, workpiece frame (normalized here).
    candidates : PostureGrid or None
    always : bool
    """

    def __init__(self, model: PostureModel, direction: Any,
                 candidates: PostureGrid | None = None, always: bool = False) -> None:
        super().__init__(model, candidates, always)
        e = np.asarray(direction, dtype=float)
        if e.shape != (3,) or not np.all(np.isfinite(e)) or np.linalg.norm(e) == 0:
            raise ValueError(f"direction: expected a finite non-zero 3-vector, got {direction!r}")
        self.direction = e / np.linalg.norm(e)

    def propose(self, state: PostureState, event: OperatorInput | Detection | None, *,
                model: PostureModel | None = None) -> PostureChange | None:
        """See the class docstring."""
        m = self._model(model)
        return self._search(state, event, m,
                            lambda lt, tt: abs(float(m.gain(lt, tt, self.direction))),
                            "process gain |e^T P e|")


class EigenCriterion(_GridRule):
    """Posture of the largest two-direction zero-order stability margin.

    Fourth embodiment, two directions ([0090]): the eigenvalues of the average
    process gain matrix with the structure's FRF give the critical scaling
    ``-(re/2)(1 + (im/re)^2)`` of their reciprocals, which is made large. The
    value comes from ``model.margin`` (orient's stability analysis); this rule
    only searches the feasible candidates. Acts like :class:`GainMinimization`.

    Parameters
    ----------
    model : PostureModel
    candidates : PostureGrid or None
    always : bool
    """

    def propose(self, state: PostureState, event: OperatorInput | Detection | None, *,
                model: PostureModel | None = None) -> PostureChange | None:
        """See the class docstring."""
        m = self._model(model)
        return self._search(state, event, m, lambda lt, tt: -float(m.margin(lt, tt)),
                            "stability margin")


# --- memory (6th embodiment) -----------------------------------------------------------
class MemoryRule(_Rule):
    """On chatter, go to the remembered chatter-free posture of the nearest conditions.

    Sixth embodiment ([0095]-[0097], claim 8, item (17), Fig. 14): without
    chatter the posture and the conditions are stored (S610, here when a
    Detection reports no chatter and ``learn`` is True; postures already
    stored within ``LEARN_DEDUPE_DISTANCE`` are not stored again); with chatter
    the stored posture is adopted (S630). Of the ``k`` nearest matches within
    ``max_distance`` (see :mod:`orient.memory`), the first feasible one that
    differs from the current posture is proposed. Needs ``state.conditions``.

    Parameters
    ----------
    model : PostureModel
    memory : PostureMemory
    k : int
    max_distance : float [-]
    learn : bool
    """

    def __init__(self, model: PostureModel, memory: PostureMemory, k: int = 5,
                 max_distance: float = DEFAULT_MEMORY_MAX_DISTANCE, learn: bool = True) -> None:
        super().__init__(model)
        if not isinstance(memory, PostureMemory):
            raise TypeError(f"memory: expected PostureMemory, got {type(memory).__name__}")
        if isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 1:
            raise ValueError(f"k: expected an integer >= 1, got {k!r}")
        self.memory, self.k = memory, int(k)
        self.max_distance = _real("max_distance", max_distance, ">=0")
        self.learn = bool(learn)

    def propose(self, state: PostureState, event: OperatorInput | Detection | None, *,
                model: PostureModel | None = None) -> PostureChange | None:
        """See the class docstring."""
        m = self._model(model)
        chatter = _is_chatter(event)
        if chatter is None:
            return self._none("no event")
        cond = state.conditions
        if cond is None:
            return self._none("memory: the state carries no cutting conditions")
        here = (state.lead_rad, state.tilt_rad)
        if not chatter:
            if not self.learn:
                return self._none("no chatter")
            for near in self.memory.nearest(cond, k=max(self.k, LEARN_DEDUPE_K),
                                            max_distance=LEARN_DEDUPE_DISTANCE):
                if _same(here, (near.entry.lead_rad, near.entry.tilt_rad)):
                    return self._none("no chatter; posture already remembered")
            self.memory.remember(cond, *here, note="learned without chatter")
            return self._none("no chatter; posture remembered")
        matches = self.memory.nearest(cond, k=self.k, max_distance=self.max_distance)
        if not matches:
            return self._none("memory: no remembered posture with similar conditions")
        for mt in matches:
            p = (mt.entry.lead_rad, mt.entry.tilt_rad)
            if _same(p, here) or not m.feasible(*p):
                continue
            return self._change(*p, f"memory: chatter-free posture at condition distance "
                                f"{mt.distance:.3g} (lead {_deg(p[0])}, tilt {_deg(p[1])})")
        return self._none("memory: no feasible remembered posture other than the current one")
