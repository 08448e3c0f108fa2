"""What a scenario's tool and resolution will cost, estimated before anything runs.

A resolution fixes the size of every per-point array: the bottom view's pixel
grid (the tool's diameter over ``pixel_mm``, squared), the side view's (steep
contacts, ``VIEW_ZOOM`` times finer, over the flute length) and the micro-edge
samples of a revolution (micro edges times rotation steps). :func:`resolution_cost`
adds them up in bytes (``BYTES_PER_PIXEL``, ``BYTES_PER_SAMPLE``); the scenario
reader (:mod:`errpred.scenario`) refuses a resolution whose estimate exceeds
:data:`errpred.constants.MEMORY_BUDGET_BYTES`, naming the key to change and the
finest value that fits, instead of running out of memory after minutes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import constants as K

__all__ = ["ResolutionCost", "resolution_cost", "revolution_steps"]


def revolution_steps(angle_step_rad: float, flutes: int) -> int:
    """How many rotation steps a revolution has (as
    :func:`errpred.engagement.revolution_angles`, without making them) [-]."""
    per_tooth = math.ceil((2 * math.pi / flutes) / angle_step_rad - 1e-9)
    n = per_tooth * flutes
    return 2 * n if n % 2 else n


@dataclass(frozen=True)
class ResolutionCost:
    """Sizes one prediction point's arrays take at a resolution.

    Attributes
    ----------
    bottom_pixels, side_pixels : float
        Pixels of the bottom view and of the (finer) side view [-].
    samples : float
        Micro-edge samples of a revolution [-].
    bytes : float
        Their estimated memory [bytes].
    """

    bottom_pixels: float
    side_pixels: float
    samples: float
    bytes: float

    @property
    def pixel_bytes(self) -> float:
        """The views' share of :attr:`bytes` [bytes]."""
        return (self.bottom_pixels + self.side_pixels) * K.BYTES_PER_PIXEL

    @property
    def sample_bytes(self) -> float:
        """The samples' share of :attr:`bytes` [bytes]."""
        return self.samples * K.BYTES_PER_SAMPLE


def resolution_cost(diameter_mm: float, corner_radius_mm: float, flute_length_mm: float,
                    flutes: int, pixel_mm: float, micro_edges: int, angle_step_rad: float) -> ResolutionCost:
    """Estimate one point's array sizes at a resolution (floats: no overflow).

    Parameters
    ----------
    diameter_mm, corner_radius_mm, flute_length_mm : float [mm]
        The tool's.
    flutes : int
    pixel_mm : float [mm]
        The bottom view's pixel; the side view's is ``pixel_mm / VIEW_ZOOM``.
    micro_edges : int
        Micro edges on the lower envelope; the flank has as many per mm.
    angle_step_rad : float [rad]
    """
    window = diameter_mm + 2 * pixel_mm
    bottom = math.ceil(window / pixel_mm) ** 2
    side_px = pixel_mm / K.VIEW_ZOOM
    side = math.ceil(window / side_px) * math.ceil(max(flute_length_mm, 2 * pixel_mm) / side_px)
    # the envelope (bottom face and corner arc) has micro_edges; the flank above it gets
    # the same spacing (errpred.tool.Tool.micro_edges)
    envelope = 0.5 * diameter_mm - corner_radius_mm + 0.5 * math.pi * corner_radius_mm
    flank = max(flute_length_mm - corner_radius_mm, 0.0)
    edges = micro_edges * (1.0 + flank / max(envelope, 1e-300))
    samples = edges * revolution_steps(angle_step_rad, flutes)
    total = (bottom + side) * K.BYTES_PER_PIXEL + samples * K.BYTES_PER_SAMPLE
    return ResolutionCost(float(bottom), float(side), float(samples), float(total))
