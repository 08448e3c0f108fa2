"""errpred.tool: the tool's dimensions at the boundary."""

from __future__ import annotations

import numpy as np
import pytest

from errpred.tool import Holder, Tool

LENGTHS = ("diameter_mm", "corner_radius_mm", "helix_deg", "flute_length_mm", "overhang_mm",
           "shank_diameter_mm")


@pytest.mark.parametrize("kind, corner", [("ball", 0), ("radius", 1), ("flat", 0)])
def test_whole_number_dimensions_are_held_as_float(kind, corner):
    """``Tool("ball", 6)``: every length and angle is a float (an int would have each
    numba kernel that takes it compiled again, for int64), with the same value."""
    whole = Tool(kind, 6, corner, 2, 30, flute_length_mm=12, overhang_mm=40,
                 shank_diameter_mm=np.int64(6), holder=Holder(20, np.int32(30)))
    real = Tool(kind, 6.0, float(corner), 2, 30.0, flute_length_mm=12.0, overhang_mm=40.0,
                shank_diameter_mm=6.0, holder=Holder(20.0, 30.0))
    for name in LENGTHS:
        assert type(getattr(whole, name)) is float, name
    assert type(whole.holder.diameter_mm) is float and type(whole.holder.length_mm) is float
    assert whole == real
    # the defaults (twice the diameter, ...) are floats too
    bare = Tool(kind, 6, corner)
    for name in LENGTHS:
        assert type(getattr(bare, name)) is float, name
    assert type(bare.core_radius_mm) is float


@pytest.mark.parametrize("name", LENGTHS)
@pytest.mark.parametrize("bad", [True, "6", None])
def test_a_dimension_that_is_not_a_number_is_refused_by_name(name, bad):
    if bad is None and name in ("flute_length_mm", "overhang_mm", "shank_diameter_mm"):
        pytest.skip("None is the default of the optional lengths")
    kw = dict(kind="radius", diameter_mm=6.0, corner_radius_mm=1.0, helix_deg=30.0)
    kw[name] = bad
    with pytest.raises(ValueError, match=f"tool.{name}: expected a number"):
        Tool(**kw)


@pytest.mark.parametrize("bad", [False, "20"])
def test_a_holder_dimension_that_is_not_a_number_is_refused_by_name(bad):
    with pytest.raises(ValueError, match="holder.length_mm: expected a number"):
        Holder(20.0, bad)
