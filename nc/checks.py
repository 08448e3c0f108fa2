"""Input checks shared by every package: a value refused names its parameter.

The lowest package holds them so that ``errpred``, ``orient`` and ``sim`` raise
the same messages for the same mistakes (NaN, infinity, a wrong sign, a
boolean where a number belongs).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

__all__ = ["real_number", "whole_number"]


def real_number(name: str, value: Any, bound: str = "") -> float:
    """``value`` as a finite float; ``bound`` ``'>0'`` or ``'>=0'`` adds a sign check.

    Raises
    ------
    TypeError
        Not a real number (booleans included).
    ValueError
        NaN, infinite, or on the wrong side of ``bound``; the message names ``name``.
    """
    # a float or numpy double (the common case) skips the abstract classes' checks
    if type(value) is not float and type(value) is not np.float64 and (
            isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real)):
        raise TypeError(f"{name}: expected a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or (bound == ">0" and v <= 0) or (bound == ">=0" and v < 0):
        limit = {">0": " > 0", ">=0": " >= 0"}.get(bound, "")
        raise ValueError(f"{name}: expected a finite value{limit}, got {value!r}")
    return v


def whole_number(name: str, value: Any, minimum: int) -> int:
    """``value`` as an int >= ``minimum`` (booleans refused); the message names ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) \
            or int(value) < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)
