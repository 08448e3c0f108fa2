"""nc.refeed.rewrite_feeds: only F words change (and are added where a feed that was
inherited would otherwise change), the program reads back with the feeds asked for."""

from __future__ import annotations

import numpy as np
import pytest

from nc import parse_program
from nc.refeed import rewrite_feeds
from nc.rewrite import RewriteError

TEXT = """%
G21 G90 G17
G0 X0 Y0 Z5 (start)
G1 Z0 F100
G1 X10 ; comment
X20 Y5
G2 X30 Y5 I5 J0 F200
G1 X40
G0 Z5
%
"""


def _prog(text: str = TEXT):
    return parse_program(text, file="t.nc")


def test_only_feed_words_change_and_inherited_feeds_are_kept():
    p = _prog()
    out = rewrite_feeds(p, {2: 150.0, 3: 120.5})
    back = parse_program(out, file="t.nc")
    np.testing.assert_array_equal(back.end, p.end)
    np.testing.assert_array_equal(back.motion, p.motion)
    want = p.feed.copy()
    want[2], want[3] = 150.0, 120.5
    np.testing.assert_allclose(back.feed[1:], want[1:])
    old, new = TEXT.splitlines(), out.splitlines()
    assert len(old) == len(new)
    # the comment stays, the F word goes before it; the line that inherited F100 gets its
    # own; the lines not touched are the same text
    assert new[4] == "G1 X10 F150 ; comment"
    assert new[5] == "X20 Y5 F120.5"
    for i in (0, 1, 2, 3, 6, 7, 8, 9):
        assert new[i] == old[i]


def test_a_later_block_that_inherited_a_changed_feed_gets_the_old_one_back():
    p = _prog()
    out = rewrite_feeds(p, {1: 90.0})          # G1 Z0 F100 -> F90
    back = parse_program(out, file="t.nc")
    assert back.feed[1] == 90.0
    assert back.feed[2] == back.feed[3] == 100.0  # X10 and X20 Y5 still at 100
    assert "G1 X10 F100 ; comment" in out.splitlines()


def test_inch_programs_write_inch_per_minute():
    p = _prog(TEXT.replace("G21", "G20"))
    out = rewrite_feeds(p, {2: 254.0})
    assert "G1 X10 F10 ; comment" in out.splitlines()
    assert parse_program(out, file="t.nc").feed[2] == pytest.approx(254.0)


@pytest.mark.parametrize("feeds, match", [
    ({0: 100.0}, "rapid move"),
    ({2: 0.0}, "finite feed > 0"),
    ({2: float("nan")}, "finite feed > 0"),
    ({99: 100.0}, "out of range"),
])
def test_bad_requests_are_refused(feeds, match):
    with pytest.raises(RewriteError, match=match):
        rewrite_feeds(_prog(), feeds)


def test_inverse_time_feed_is_refused():
    p = _prog("G21 G90\nG0 X0 Y0 Z0\nG93 G1 X10 F2\nG94 G1 X20 F100\n")
    with pytest.raises(RewriteError, match="G93"):
        rewrite_feeds(p, {2: 50.0})


def test_feeds_a_unit_apart_get_their_own_words():
    """2599 then 2600 mm/min: the second is not the first within any relative share."""
    p = _prog()
    out = rewrite_feeds(p, {2: 2599.0, 3: 2600.0, 4: 2600.0})
    back = parse_program(out, file="t.nc")
    assert back.feed[2] == 2599.0 and back.feed[3] == back.feed[4] == 2600.0


def test_hash_and_brackets_in_comments_do_not_stop_a_refeed():
    text = "(T1 #2 ball)\nG21 G90 (units [G20 inch])\nG0 X0 Y0 Z5\nG1 Z0 F100\nG1 X10\n"
    out = rewrite_feeds(_prog(text), {2: 150.0})
    assert out.splitlines()[:4] == text.splitlines()[:4]
    np.testing.assert_allclose(_prog(out).feed[1:3], [100.0, 150.0])
    with pytest.raises(RewriteError, match=r"^t\.nc:5: rewriting programs with '#'"):
        rewrite_feeds(_prog(text.replace("G1 X10", "#1=10\nG1 X#1")), {2: 150.0})
