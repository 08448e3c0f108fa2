"""The cut's periodic forced response, and what a change of cut does to the simulated
machine's state (``docs/method.md`` §8): a machine moves its posture and its
cutting point continuously, the simulation per cutter location."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import _kernels as _k

if TYPE_CHECKING:
    from .cutting_model import CuttingModel

__all__ = ["engaged_cells", "forced_response", "mid_step_displacement"]


def forced_response(model: CuttingModel, scale: float = 1.0) -> np.ndarray:
    """The modes' periodic forced response to the cut's static chips (no regeneration):
    ``(eta, eta')`` at the start of each rotation step of a revolution, shape
    (steps_per_rev, nm, 2) [m, m/s].

    A machine moves its posture and its cutting point continuously, slowly
    against the modes' periods, so its vibration follows the cut's forced
    response (where the cut is stable, regeneration leaves a tooth-periodic
    response as it is). The simulation changes its cut per cutter location;
    :meth:`sim.cutter.Cutter.switch` moves the state by the change of this response when it
    does, so the change does not ring the modes like a hammer blow, which no
    machine does.

    The response is the revolution-periodic solution of the step map ``x[p + 1] = phi
    x[p] + gam u[p]`` (``model.step_map``; ``u`` the static force on each mode): per
    mode ``x[0] = (I - phi^spr)^-1 sum_p phi^(spr-1-p) gam u[p]``, then the steps
    (:func:`sim._kernels.periodic_forced`, two passes over the revolution)."""
    ptr, _pos, _e, h0, _nrm, f0, f1 = model.table
    spr = model.steps_per_rev
    nm = model.system.n_modes
    x = np.zeros((spr, nm, 2))
    if ptr[-1] == 0 or scale == 0.0:
        return x
    phi, gam = model.step_map
    _k.periodic_forced(ptr, h0, f0, f1, float(scale),
                       np.ascontiguousarray(model.system.direction, dtype=float),
                       np.ascontiguousarray(phi), np.ascontiguousarray(gam), x)
    if not np.isfinite(x).all():
        bad = np.flatnonzero(~np.isfinite(x).all(axis=(0, 2)))
        raise ValueError(f"model: no periodic forced response: mode(s) {bad.tolist()} "
                         f"undamped at a multiple of the revolution frequency (or a "
                         f"non-finite force table)")
    return x


def mid_step_displacement(model: CuttingModel, x: np.ndarray) -> np.ndarray:
    """Relative displacement [m], shape (spr, 3), that the kernel's chips use (the middle
    of each step) from the modes' states ``x`` (spr, nm, 2) at the steps' starts."""
    sysm = model.system
    r = (0.5 * model.dt_s + sysm.velocity_s)[None, :]
    return (x[:, :, 0] + r * x[:, :, 1]) @ sysm.direction


def engaged_cells(model: CuttingModel, n_edges: int) -> np.ndarray:
    """Places of the surface memory (rotation position, micro edge) the cut engages,
    shape (spr, n_edges) of bool."""
    _ptr, pos, edge, _h0, _nrm, _f0, _f1 = model.table
    out = np.zeros((model.steps_per_rev, n_edges), bool)
    out[pos, edge] = True
    return out
