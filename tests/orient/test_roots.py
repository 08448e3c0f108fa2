"""orient._root_kernels.illinois, the kernels' one root finder, against its numpy twin and
scipy.optimize.brentq."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from scipy.optimize import brentq

from orient._root_kernels import illinois


def _illinois_twin(f, args, a, fa, b, fb, xtol, rtol, maxit):
    """numpy twin of :func:`orient._root_kernels.illinois`."""
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    side, width_before = 0, abs(b - a)
    ends = {a: abs(fa), b: abs(fb)}
    for it in range(maxit):
        width = abs(b - a)
        if width <= xtol + rtol * max(abs(a), abs(b)):
            break
        if it % 2 == 0:
            if it > 0 and width > 0.5 * width_before:
                side = 2
            width_before = width
        x = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if side == 2 or not min(a, b) < x < max(a, b):
            x, side = 0.5 * (a + b), 0
        fx = f(x, *args)
        if fx == 0.0:
            return x
        ends[x] = abs(fx)
        if np.sign(fx) == np.sign(fa):
            a, fa = x, fx
            fb, side = (0.5 * fb if side == -1 else fb), -1
        else:
            b, fb = x, fx
            fa, side = (0.5 * fa if side == 1 else fa), 1
    return a if ends[a] <= ends[b] else b


@njit(cache=True)
def _cubic(x, c):
    return x * x * x - 2.0 * x - c


@njit(cache=True)
def _flat_side(x, c):
    """Zero up to the root's left, a steep rise after: stalls plain regula falsi."""
    t = max(x - c, 0.0)
    t2 = t * t
    return t2 * t2 * t2 - 1e-12


@njit(cache=True)
def _transcendental(x, c):
    return math.cos(x) - c * x


@njit(cache=True)
def _steep(x, c):
    return math.tanh(50.0 * (x - c))


@njit(cache=True)
def _solve(which, c, a, b, xtol, rtol, maxit):
    if which == 0:
        return illinois(_cubic, (c,), a, _cubic(a, c), b, _cubic(b, c), xtol, rtol, maxit)
    if which == 1:
        return illinois(_flat_side, (c,), a, _flat_side(a, c), b, _flat_side(b, c), xtol, rtol,
                        maxit)
    if which == 2:
        return illinois(_transcendental, (c,), a, _transcendental(a, c), b,
                        _transcendental(b, c), xtol, rtol, maxit)
    return illinois(_steep, (c,), a, _steep(a, c), b, _steep(b, c), xtol, rtol, maxit)


FUNCS = [_cubic, _flat_side, _transcendental, _steep]
CASES = [(0, 1.0, 0.0, 3.0), (0, -3.0, -3.0, 1.0), (1, 0.3, -1.0, 2.0), (2, 0.5, 0.0, 2.0),
         (2, 4.0, 2.0, 0.0), (3, 0.123, -1.0, 1.0), (3, -0.7, 1.0, -1.0)]


@pytest.mark.parametrize("which, c, a, b", CASES)
@pytest.mark.parametrize("xtol, rtol", [(1e-12, 0.0), (0.0, 1e-10), (1e-6, 0.0)])
def test_illinois_equals_its_twin_and_brentq(which, c, a, b, xtol, rtol) -> None:
    f = FUNCS[which].py_func
    root = _solve(which, c, a, b, xtol, rtol, 200)
    twin = _illinois_twin(f, (c,), a, f(a, c), b, f(b, c), xtol, rtol, 200)
    assert root == twin
    ref = brentq(f, min(a, b), max(a, b), args=(c,), xtol=1e-15, rtol=1e-15)
    assert abs(root - ref) <= xtol + rtol * max(abs(a), abs(b)) + 1e-12


def test_few_evaluations_where_plain_regula_falsi_stalls() -> None:
    """The flat-sided function: with the bisection steps 30 evaluations (plain Illinois
    takes 93 here)."""
    calls = []

    def f(x, c):
        calls.append(x)
        return _flat_side.py_func(x, c)

    root = _illinois_twin(f, (0.3,), -1.0, f(-1.0, 0.3), 2.0, f(2.0, 0.3), 1e-10, 0.0, 500)
    assert abs(root - (0.3 + 1e-2)) < 1e-9
    assert len(calls) <= 40


def test_exact_zero_and_zero_at_an_end() -> None:
    assert _solve(0, 0.0, 0.0, 3.0, 1e-12, 0.0, 50) == 0.0          # f(a) = 0
    assert _solve(3, 0.5, -1.0, 2.0, 0.0, 0.0, 50) == 0.5            # the secant hits it
