"""Chatter stability of orient: zero-order (ZOA) and time-periodic analyses.

See :mod:`orient.stability.zoa` for the shared sign conventions (the
contract): ``F = s H(t) (q(t) - q(t - tau))``, ``P = mean H`` [N/m],
``q = G(i w) F``; the margin is the smallest positive ``s`` on the
stability boundary (> 1 stable).
"""

from __future__ import annotations

from orient.stability.lobes import Lobes, stability_lobes
from orient.stability.milling2d import StraightEndMill2D
from orient.stability.sdm import (
    SdmResult,
    default_steps,
    floquet_multipliers,
    recommended_samples,
    sdm_lobes,
    sdm_margin,
)
from orient.stability.zoa import (
    ZoaCritical,
    zoa_critical,
    zoa_frequency_grid,
    zoa_lobes,
    zoa_margin,
    zoa_margin_batch,
)

__all__ = [
    "Lobes",
    "SdmResult",
    "StraightEndMill2D",
    "ZoaCritical",
    "default_steps",
    "floquet_multipliers",
    "recommended_samples",
    "sdm_lobes",
    "sdm_margin",
    "stability_lobes",
    "zoa_critical",
    "zoa_frequency_grid",
    "zoa_lobes",
    "zoa_margin",
    "zoa_margin_batch",
]
