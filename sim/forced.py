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


def forced_response(model: CuttingModel, scale: float = 1.0,
                    parts: dict | None = None) -> np.ndarray:
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

    ``parts`` (optional, a dict the caller keeps) holds what does not change from call
    to call: the static force of each engagement table and the eigen-decomposition of
    each step map (a cutter location's two cuts share its dynamics, a pass's cutter
    locations share their tables); the same numbers bit for bit as without it."""
    ptr = model.table[0]
    spr = model.steps_per_rev
    nm = model.system.n_modes
    if ptr[-1] == 0 or scale == 0.0:
        return np.zeros((spr, nm, 2))
    force = _kept(parts, ("force", float(scale)), model.table,
                  lambda: _static_force(model.table, spr, scale))
    u = force @ model.system.direction.T                     # (spr, nm)
    # x_{n+1} = phi x_n + gam u_n per mode; in phi's eigenvectors each component is
    # w_p = lam^p w_0 + z t_p, t_{p+1} = lam t_p + u_p (z = V^-1 gam): a first-order filter
    lam, vec, z, powers, period = _kept(parts, ("modes", spr), model.step_map,
                                        lambda: _eigen_steps(model.step_map, spr))
    tail = np.empty((spr + 1, nm, 2), complex)
    neg = np.ascontiguousarray((-lam).astype(complex))      # lfilter's a[1] per mode
    _k.forced_tail(np.ascontiguousarray(u), neg, tail)
    w0 = z * tail[spr] / period
    w = powers * w0[None] + z[None] * tail[:-1]
    return np.einsum("mij,pmj->pmi", vec, w).real


#: Entries kept in a ``parts`` dict of :func:`forced_response` before it is emptied [-].
_PARTS_KEPT = 64


def _kept(parts: dict | None, kind: tuple, owner, make):
    """``make()``, kept in ``parts`` under ``kind`` and ``owner``'s identity (the owner is
    kept with it, so the identity cannot be reused while the entry lives)."""
    if parts is None:
        return make()
    key = (*kind, id(owner))
    hit = parts.get(key)
    if hit is not None and hit[0] is owner:
        return hit[1]
    if len(parts) >= _PARTS_KEPT:
        parts.clear()
    value = make()
    parts[key] = (owner, value)
    return value


def _static_force(table: tuple, spr: int, scale: float) -> np.ndarray:
    """The force of a table's static chips per rotation sample [N], shape (spr, 3)."""
    ptr, _pos, _e, h0, _nrm, f0, f1 = table
    sample = np.repeat(np.arange(spr), np.diff(ptr))
    fe = scale * (f0 + h0[:, None] * f1)
    return np.stack([np.bincount(sample, fe[:, a], minlength=spr) for a in range(3)], axis=1)


def _eigen_steps(step_map: tuple, spr: int) -> tuple:
    """A step map's eigenvalues and eigenvectors per mode, ``z = V^-1 gam``, the powers
    ``lam^p`` for p = 0 .. spr - 1 and ``1 - lam^spr``."""
    phi, gam = step_map
    nm = phi.shape[0]
    lam, vec = np.linalg.eig(phi)                            # (nm, 2), (nm, 2, 2)
    z = np.linalg.solve(vec, gam[..., None].astype(complex))[..., 0]
    powers = np.cumprod(np.concatenate([np.ones((1, nm, 2), complex),
                                        np.broadcast_to(lam, (spr - 1, nm, 2))]), axis=0)
    return lam, vec, z, powers, 1.0 - lam ** spr


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
