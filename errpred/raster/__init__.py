"""Software depth-buffer rasterizer for the engagement views (``docs/method.md`` §3).

* :class:`View` (``camera.py``): orthographic pixel grid, bottom and side
  views in the tool frame, zoomed views.
* :class:`Stock` (``meshes.py``): STL / mesh / analytic box stock; per view
  the depth interval ``(bottom, top)`` of its material (first entry, first
  exit), drawing only the triangles a :class:`TriangleGrid` finds near the
  window.
* :func:`rasterize_interval`, :func:`material_at`, :class:`StockInterval`
  (``depth.py``): the same for any triangle mesh, and point membership.

The numba kernels live in ``_kernels.py`` (compiled on first use, cached).
"""

from .camera import View
from .depth import StockInterval, coverage, material_at, rasterize_interval, view_triangles
from .meshes import Stock, TriangleGrid

__all__ = [
    "View",
    "Stock",
    "TriangleGrid",
    "StockInterval",
    "rasterize_interval",
    "coverage",
    "material_at",
    "view_triangles",
]
