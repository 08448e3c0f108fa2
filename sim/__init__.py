"""The simulated machine: time-domain cutting with regeneration (``docs/method.md`` §8)."""

from .cutting import (
    Cutter,
    CuttingModel,
    MillingRun,
    growth_rate,
    prepare_cut,
    simulate,
    stability_boundary,
)

__all__ = [
    "Cutter",
    "CuttingModel",
    "MillingRun",
    "growth_rate",
    "prepare_cut",
    "simulate",
    "stability_boundary",
]
