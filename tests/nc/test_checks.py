"""The shared input checks name the parameter and refuse NaN, infinity, booleans, signs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nc.checks import real_number, whole_number


@pytest.mark.parametrize("value, bound", [(math.nan, ""), (math.inf, ""), (-1.0, ">=0"),
                                          (0.0, ">0"), (np.float64("nan"), ">0")])
def test_real_number_refuses_with_the_name(value, bound):
    with pytest.raises(ValueError, match="spindle_rpm: expected a finite value"):
        real_number("spindle_rpm", value, bound)


def test_real_number_types():
    assert real_number("x", np.float32(2.5)) == 2.5 and real_number("x", 3) == 3.0
    # floats and numpy's doubles take the short path: a plain float back, as the others
    for v in (2.5, np.float64(2.5), np.float32(2.5), 2):
        assert type(real_number("x", v)) is float
    with pytest.raises(TypeError, match="x: expected a real number"):
        real_number("x", True)
    with pytest.raises(TypeError):
        real_number("x", "1.0")


def test_whole_number():
    assert whole_number("teeth", np.int64(4), 1) == 4
    for bad in (0, True, 2.0, -3):
        with pytest.raises(ValueError, match="teeth: expected an integer >= 1"):
            whole_number("teeth", bad, 1)
