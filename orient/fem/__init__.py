"""Finite-element helpers of :mod:`orient.workpiece_fem` (structured quadratic hexahedra).

The public workpiece API is :mod:`orient.workpiece_fem`; this package holds its
numerical kernel (:mod:`orient.fem.q2hex`).
"""

__all__: list[str] = []
