"""errpred.tool: the tool's dimensions at the boundary."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from errpred.tool import Holder, Tool

LENGTHS = ("diameter_mm", "corner_radius_mm", "helix_deg", "flute_length_mm", "overhang_mm",
           "shank_diameter_mm")
OPTIONAL = ("flute_length_mm", "overhang_mm", "shank_diameter_mm")


@pytest.mark.parametrize("kind, corner", [("ball", 0), ("radius", 1), ("flat", 0)])
def test_whole_number_dimensions_are_held_as_float(kind, corner):
    """Every length and angle given as an int (or a numpy or fractional number) is held as
    a float of the same value: an int flute length (``flute_length_mm=15``) had every numba
    kernel that takes it compiled again, for int64."""
    whole = Tool(kind, 6, corner, 2, 30, flute_length_mm=12, overhang_mm=np.int32(40),
                 shank_diameter_mm=np.int64(6), holder=Holder(20, Fraction(61, 2)))
    real = Tool(kind, 6.0, float(corner), 2, 30.0, flute_length_mm=12.0, overhang_mm=40.0,
                shank_diameter_mm=6.0, holder=Holder(20.0, 30.5))
    for name in LENGTHS:
        assert type(getattr(whole, name)) is float, name
        assert getattr(whole, name) == getattr(real, name), name
    for name in ("diameter_mm", "length_mm"):
        assert type(getattr(whole.holder, name)) is float, name
    assert whole == real and hash(whole) == hash(real)
    # the defaults (twice the diameter, ...) are floats too
    bare = Tool(kind, 6, corner)
    for name in LENGTHS:
        assert type(getattr(bare, name)) is float, name


@pytest.mark.parametrize("name", LENGTHS)
@pytest.mark.parametrize("bad", [True, "6", None])
def test_a_dimension_that_is_not_a_number_is_refused_by_name(name, bad):
    if bad is None and name in OPTIONAL:
        pytest.skip("None is the default of the optional lengths")
    kw = dict(kind="radius", diameter_mm=6.0, corner_radius_mm=1.0, helix_deg=30.0)
    kw[name] = bad
    with pytest.raises(TypeError, match=f"tool.{name}: expected a real number"):
        Tool(**kw)


@pytest.mark.parametrize("kind, want", [("ball", 3.0), ("flat", 0.0)])
@pytest.mark.parametrize("given", [None, "any", 1.0])
def test_a_ball_or_flat_end_mills_corner_radius_is_ignored(kind, want, given):
    assert Tool(kind, 6.0, given).corner_radius_mm == want


@pytest.mark.parametrize("name", ["diameter_mm", "length_mm"])
@pytest.mark.parametrize("bad, error", [(False, TypeError), ("20", TypeError),
                                        (float("nan"), ValueError), (0, ValueError)])
def test_a_holder_dimension_that_is_not_a_positive_number_is_refused_by_name(name, bad,
                                                                              error):
    kw = dict(diameter_mm=20.0, length_mm=30.0)
    kw[name] = bad
    with pytest.raises(error, match=f"holder.{name}: expected a"):
        Holder(**kw)
