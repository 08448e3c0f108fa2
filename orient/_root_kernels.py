"""The root finder of orient's numba kernels: Illinois regula falsi on a bracket.

One function, :func:`illinois`, used by every kernel that refines a sign change
to a root: the engagement's material margin along a micro edge's circle
(:mod:`orient._engagement_kernels`), the band of the cutting profile
(:mod:`orient._kernels`) and the zero-order margin's phase crossings
(:mod:`orient.stability._kernels`). Its numpy twin, compared with it and with
``scipy.optimize.brentq``, is in ``tests/orient/test_roots.py``.

It is inlined where it is called (``inline="always"``): called across a function
boundary, the function it is given would be passed as an object's address, and
numba does not cache a kernel holding one. Inlined, it is compiled into its
callers' cache entries, which numba keys by the callers' own files: after a change
here, remove the ``orient`` numba caches (``__pycache__/*.nbi``, ``*.nbc``).
"""

from __future__ import annotations

from numba import njit

__all__ = ["illinois"]


@njit(cache=True, inline="always")
def illinois(f, args, a, fa, b, fb, xtol, rtol, maxit):
    """Root of ``f(x, *args)`` between ``a`` and ``b``, where it changes sign.

    Illinois regula falsi (the secant through the bracket's ends; the end kept
    twice in a row has its value halved), with a bisection step whenever two
    steps have not halved the bracket (a function flat on one side would stall
    it otherwise).

    Parameters
    ----------
    f : numba function
        ``f(x, *args) -> float``.
    args : tuple
        Its further arguments.
    a, b : float
        The bracket's ends [unit of x], in either order.
    fa, fb : float
        ``f`` there, of opposite signs (or one of them zero) [unit of f].
    xtol, rtol : float
        Stop once the bracket is at most ``xtol + rtol max(|a|, |b|)`` wide
        [unit of x; -].
    maxit : int
        Most evaluations of ``f``.

    Returns
    -------
    float
        The end of the last bracket where ``|f|`` is smaller (once the secant steps
        converge, the last of them, far closer to the root than the bracket's
        width) [unit of x], or the point where ``f`` is exactly zero.
    """
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    side = 0
    width_before = abs(b - a)
    abs_fa, abs_fb = abs(fa), abs(fb)   # |f| at the ends (fa, fb get halved)
    for it in range(maxit):
        width = abs(b - a)
        if width <= xtol + rtol * max(abs(a), abs(b)):
            break
        if it % 2 == 0:
            if it > 0 and width > 0.5 * width_before:
                side = 2
            width_before = width
        den = fb - fa
        x = (a * fb - b * fa) / den if den != 0.0 else 0.5 * (a + b)
        if side == 2 or not (min(a, b) < x < max(a, b)):
            x = 0.5 * (a + b)
            side = 0
        fx = f(x, *args)
        if fx == 0.0:
            return x
        if (fx > 0.0) == (fa > 0.0):
            a, fa, abs_fa = x, fx, abs(fx)
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b, fb, abs_fb = x, fx, abs(fx)
            if side == 1:
                fa *= 0.5
            side = 1
    return a if abs_fa <= abs_fb else b
