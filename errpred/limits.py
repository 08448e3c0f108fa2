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
from typing import TYPE_CHECKING

from . import constants as K

if TYPE_CHECKING:
    from .geometry import Resolution
    from .tables import TableReader
    from .tool import Tool

__all__ = ["ResolutionCost", "check_resolution_budget", "resolution_cost", "revolution_steps"]


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


def check_resolution_budget(r: TableReader, d: dict, tool: Tool, res: Resolution) -> None:
    """Refuse (``r.fail``: the scenario file and the key to change) a resolution whose
    arrays would not fit :data:`errpred.constants.MEMORY_BUDGET_BYTES`; ``d`` is the
    ``[resolution]`` table as given (which keys the file sets)."""
    def cost(pixel_mm: float):
        return resolution_cost(tool.diameter_mm, tool.corner_radius_mm, tool.flute_length_mm,
                               tool.flutes, pixel_mm, res.micro_edges, res.angle_step_rad)

    c, budget = cost(res.pixel_mm), K.MEMORY_BUDGET_BYTES
    if c.bytes <= budget:
        return
    over = (f"about {c.bytes / 2**30:.3g} GiB a prediction point, over the budget of "
            f"{budget / 2**30:g} GiB (errpred.constants.MEMORY_BUDGET_BYTES)")
    if c.sample_bytes < budget / 2:
        # the views dominate: the coarsest pixel that fits (their size goes as 1/pixel^2)
        p = res.pixel_mm * math.sqrt(c.pixel_bytes / (budget - c.sample_bytes))
        while cost(p).bytes > budget:
            p *= 1.01
        step = 10.0 ** (math.floor(math.log10(p)) - 2)  # 3 digits, rounded up: it fits
        p = math.ceil(p / step) * step
        raise r.fail("resolution.pixel_mm", f"{res.pixel_mm:g} mm makes views of "
                                            f"{c.bottom_pixels:.3g} + {c.side_pixels:.3g} "
                                            f"pixels (tool {tool.diameter_mm:g} mm, flutes "
                                            f"{tool.flute_length_mm:g} mm long), {over}; "
                                            f"expected pixel_mm >= {p:.3g}")
    key = "angle_step_deg" if "angle_step_deg" in d or "micro_edges" not in d else "micro_edges"
    raise r.fail(f"resolution.{key}", f"micro_edges {res.micro_edges} and angle_step_deg "
                                      f"{math.degrees(res.angle_step_rad):g} make "
                                      f"{c.samples:.3g} micro-edge samples a revolution, "
                                      f"{over}; expected a coarser angle_step_deg or fewer "
                                      f"micro_edges")
