"""3-D linear elasticity on a structured grid of triquadratic (27-node) hexahedra.

The domain is a union of axis-aligned boxes ("voxels") of a tensor grid: element
boundaries ``lines[d]`` along each axis ``d`` and a mask of the cells that hold
material. Each active cell is a 27-node Lagrange (Q2) hexahedron; its nodes are
the cell's corners, edge and face midpoints and centre. Quadratic elements are
used because linear hexahedra lock in bending: a thin wall needs no more than
one Q2 element through its thickness.

Because every element is a box, its matrices are exact tensor products of 1-D
integrals (no quadrature): with ``N_i = l_a(x) l_b(y) l_c(z)``,
``int dN_i/dx dN_j/dx dV = K1(a,a') M1(b,b') M1(c,c') * hy hz / hx`` and so on.
Isotropic elasticity (Lame ``lam``, ``mu``) gives
``K[(i,al),(j,be)] = lam G_al,be + mu G_be,al + mu delta_al,be sum_g G_g,g`` with
``G_p,q[i,j] = int dN_i/dx_p dN_j/dx_q dV``; consistent mass
``M[(i,al),(j,be)] = rho delta_al,be int N_i N_j dV``.

(scikit-fem's generic assembly of the same element gives the same matrices,
see the tests, but takes seconds to minutes for a wall mesh; the tensor
products take a fraction of a second.)

Units are whatever the caller uses consistently (orient.workpiece_fem uses SI:
m, Pa, kg/m^3, so K is in N/m, M in kg and eigenvalues in (rad/s)^2).
Local DOF order: ``3 * local_node + component``; local node order
``9 a + 3 b + c`` with ``a, b, c`` in {0, 1, 2} the node's position along x, y, z.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, eigsh, splu

from orient.blas import blas_limited
from orient.constants import ASSEMBLY_BATCH, EIGEN_SEED, EIGEN_TOL, ND_LEAF_ELEMENTS

__all__ = ["Q2Mesh", "assemble", "build_mesh", "lowest_modes", "nested_dissection",
           "shape_functions"]

#: Fill-reducing ordering for the sparse LU of the stiffness (symmetric pattern) where
#: no node order is given (:func:`lowest_modes`).
LU_ORDERING = "MMD_AT_PLUS_A"


def _l(x: np.ndarray) -> np.ndarray:
    """1-D quadratic Lagrange functions at nodes 0, 1/2, 1; shape (3, *x.shape)."""
    x = np.asarray(x, dtype=float)
    return np.array([2.0 * (x - 0.5) * (x - 1.0), -4.0 * x * (x - 1.0), 2.0 * x * (x - 0.5)])


def _dl(x: np.ndarray) -> np.ndarray:
    """Derivatives of :func:`_l`; shape (3, *x.shape)."""
    x = np.asarray(x, dtype=float)
    return np.array([4.0 * x - 3.0, 4.0 - 8.0 * x, 4.0 * x - 1.0])


def _reference_1d() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact 1-D integrals on [0, 1] (3-point Gauss is exact to degree 5):
    ``M1 = int l l``, ``K1 = int l' l'``, ``D1[a, b] = int l_a' l_b``."""
    g, w = np.polynomial.legendre.leggauss(3)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    v, d = _l(g), _dl(g)
    return (v * w) @ v.T, (d * w) @ d.T, (d * w) @ v.T


_M1, _K1, _D1 = _reference_1d()


def _g_ref(p: int, q: int) -> np.ndarray:
    """``int dN_i/dx_p dN_j/dx_q`` over the unit cube, shape (27, 27)."""
    mats = []
    for d in range(3):
        if d == p and d == q:
            mats.append(_K1)
        elif d == p:
            mats.append(_D1)
        elif d == q:
            mats.append(_D1.T)
        else:
            mats.append(_M1)
    return np.kron(np.kron(mats[0], mats[1]), mats[2])


def _elastic_ref(lam: float, mu: float) -> np.ndarray:
    """Unit-cube stiffness parts ``A[p, q]`` (81 x 81) such that a box of sides h
    has ``K_e = sum_pq (h0 h1 h2 / (h_p h_q)) A[p, q]``; shape (3, 3, 81, 81)."""
    out = np.zeros((3, 3, 27, 3, 27, 3))
    for p in range(3):
        for q in range(3):
            g = _g_ref(p, q)
            out[p, q, :, p, :, q] += lam * g
            out[p, q, :, q, :, p] += mu * g
            if p == q:
                for a in range(3):
                    out[p, q, :, a, :, a] += mu * g
    return out.reshape(3, 3, 81, 81)


_MASS_REF = np.kron(np.kron(np.kron(_M1, _M1), _M1), np.eye(3))  # (81, 81), unit cube, rho = 1


def shape_functions(xi: np.ndarray) -> np.ndarray:
    """Q2 shape functions at reference coordinates ``xi`` in [0, 1]^3.

    Parameters
    ----------
    xi : ndarray, shape (3,) [-]
        Position inside the element, each coordinate 0 at the lower and 1 at
        the upper face.

    Returns
    -------
    ndarray, shape (27,) [-]
        Values in local node order ``9 a + 3 b + c``.
    """
    lx, ly, lz = _l(xi[0]), _l(xi[1]), _l(xi[2])
    return np.einsum("a,b,c->abc", lx, ly, lz).ravel()


@dataclass(frozen=True, eq=False)
class Q2Mesh:
    """Active Q2 elements of a tensor grid.

    Attributes
    ----------
    lines : tuple of 3 ndarray
        Element boundaries along x, y, z (increasing) [length unit].
    cells : ndarray, shape (E, 3) int
        Grid index (i, j, k) of each active element.
    elements : ndarray, shape (E, 27) int
        Node numbers of each element, local order ``9 a + 3 b + c``.
    nodes : ndarray, shape (N, 3) [length unit]
        Node coordinates.
    """

    lines: tuple[np.ndarray, np.ndarray, np.ndarray]
    cells: np.ndarray
    elements: np.ndarray
    nodes: np.ndarray

    @property
    def lower(self) -> np.ndarray:
        """Lower corner of each element, shape (E, 3)."""
        return self.boxes()[0]

    @property
    def upper(self) -> np.ndarray:
        """Upper corner of each element, shape (E, 3)."""
        return self.boxes()[1]

    def boxes(self, ids=slice(None)) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners of the elements ``ids`` (all by default), each
        shape (len(ids), 3)."""
        cells = self.cells[ids]
        return (np.stack([self.lines[d][cells[:, d]] for d in range(3)], axis=1),
                np.stack([self.lines[d][cells[:, d] + 1] for d in range(3)], axis=1))

    @cached_property
    def _grid_element(self) -> np.ndarray:
        """Element number of each grid cell, -1 where none (n0, n1, n2)."""
        out = np.full(tuple(len(x) - 1 for x in self.lines), -1, dtype=np.int64)
        out[self.cells[:, 0], self.cells[:, 1], self.cells[:, 2]] = np.arange(len(self.cells))
        return out

    def elements_near(self, point, reach: float) -> np.ndarray:
        """Element numbers (ascending) of every element whose box comes within ``reach``
        of ``point`` (3,) along each axis: a superset of those within ``reach`` of it.
        From the grid lines (a binary search per axis), not a pass over every element."""
        box = []
        for d in range(3):
            x = self.lines[d]
            lo = max(int(np.searchsorted(x, point[d] - reach, "left")) - 1, 0)
            hi = min(int(np.searchsorted(x, point[d] + reach, "right")) - 1, len(x) - 2)
            if hi < lo:
                return np.zeros(0, dtype=np.int64)
            box.append(slice(lo, hi + 1))
        ids = self._grid_element[tuple(box)].ravel()
        return np.sort(ids[ids >= 0])


def build_mesh(lines: tuple[np.ndarray, np.ndarray, np.ndarray], active: np.ndarray) -> Q2Mesh:
    """Q2 mesh of the active cells of a tensor grid.

    Parameters
    ----------
    lines : tuple of 3 ndarray, shapes (n0 + 1,), (n1 + 1,), (n2 + 1,)
        Strictly increasing element boundaries per axis.
    active : ndarray of bool, shape (n0, n1, n2)
        True for cells that hold material.
    """
    lines = tuple(np.asarray(x, dtype=float) for x in lines)
    cells = np.argwhere(active)
    nq = [2 * (len(x) - 1) + 1 for x in lines]  # quadratic nodes per axis
    abc = np.stack(np.meshgrid(np.arange(3), np.arange(3), np.arange(3), indexing="ij"),
                   axis=-1).reshape(27, 3)
    ijk = 2 * cells[:, None, :] + abc[None, :, :]  # (E, 27, 3) quadratic grid index
    full = (ijk[..., 0] * nq[1] + ijk[..., 1]) * nq[2] + ijk[..., 2]
    used, elements = np.unique(full, return_inverse=True)
    elements = elements.reshape(full.shape)
    qlines = []
    for x in lines:
        q = np.empty(2 * len(x) - 1)
        q[0::2], q[1::2] = x, 0.5 * (x[:-1] + x[1:])
        qlines.append(q)
    i0, rest = np.divmod(used, nq[1] * nq[2])
    i1, i2 = np.divmod(rest, nq[2])
    nodes = np.stack([qlines[0][i0], qlines[1][i1], qlines[2][i2]], axis=1)
    return Q2Mesh(lines=lines, cells=cells, elements=elements, nodes=nodes)


def assemble(mesh: Q2Mesh, lam: float, mu: float, rho: float) -> tuple[sp.csr_matrix,
                                                                       sp.csr_matrix]:
    """Stiffness and consistent mass matrices, DOF ``3 * node + component``.

    Parameters
    ----------
    mesh : Q2Mesh
    lam, mu : float
        Lame parameters [stress unit].
    rho : float
        Density [mass / length^3].

    Returns
    -------
    K, M : scipy.sparse.csr_matrix, shape (3N, 3N)
    """
    h = mesh.upper - mesh.lower  # (E, 3)
    vol = np.prod(h, axis=1)
    ref = _elastic_ref(lam, mu)
    dofs = (3 * mesh.elements[:, :, None] + np.arange(3)).reshape(-1, 81).astype(np.int64)
    n = 3 * len(mesh.nodes)
    K = sp.csr_matrix((n, n))
    M = sp.csr_matrix((n, n))
    for s in range(0, len(h), ASSEMBLY_BATCH):
        hb, vb, db = h[s:s + ASSEMBLY_BATCH], vol[s:s + ASSEMBLY_BATCH], dofs[s:s + ASSEMBLY_BATCH]
        scale = vb[:, None, None] / (hb[:, :, None] * hb[:, None, :])  # (b, 3, 3)
        ke = np.einsum("epq,pqij->eij", scale, ref)
        me = (rho * vb)[:, None, None] * _MASS_REF
        rows = np.repeat(db, 81, axis=1).ravel()
        cols = np.tile(db, (1, 81)).ravel()
        K = K + sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(n, n))
        M = M + sp.csr_matrix((me.ravel(), (rows, cols)), shape=(n, n))
    return K, M


def nested_dissection(mesh: Q2Mesh, leaf: int = ND_LEAF_ELEMENTS) -> np.ndarray:
    """A fill-reducing order of the mesh's nodes (each node once) for a sparse
    factorization: nested dissection by the elements' geometry.

    The elements are split in two at the median of their centres along the direction
    in which those spread most (at the lowest value where half or more sit there); the
    nodes both halves share separate them (no element couples a node of one half to
    one of the other) and come after both halves, each half ordered the same way, down
    to parts of ``leaf`` elements or fewer (their nodes in number order). Every node is
    in exactly one part or separator. The factor's fill stays within the parts and
    their separators.

    Parameters
    ----------
    mesh : Q2Mesh
    leaf : int
        Largest part not split further, >= 1.

    Returns
    -------
    ndarray of int, shape (N,)
        Node numbers, in the order to eliminate them.
    """
    if not (isinstance(leaf, (int, np.integer)) and leaf >= 1):
        raise ValueError(f"leaf: expected an integer >= 1, got {leaf!r}")
    elements = mesh.elements
    n = mesh.nodes.shape[0]
    centre = mesh.nodes[elements].mean(axis=1)
    parts: list[np.ndarray] = []

    def nodes_of(el: np.ndarray, own: np.ndarray) -> np.ndarray:
        mask = np.zeros(n, dtype=bool)
        mask[elements[el].ravel()] = True
        return mask & own

    def halves(el: np.ndarray) -> np.ndarray | None:
        """Which of ``el`` go to the first half (None: no split): below the median
        along the widest spread, or, where half or more sit at the lowest value, those
        at it; the next widest direction where all sit at one value."""
        c = centre[el]
        spread = np.ptp(c, axis=0)
        for axis in np.argsort(-spread, kind="stable"):
            v = c[:, axis]
            for below in (v < np.median(v), v <= v.min()):
                if below.any() and not below.all():
                    return below
        return None

    def split(el: np.ndarray, own: np.ndarray) -> None:
        below = halves(el) if el.size > leaf else None
        if below is None:
            parts.append(np.flatnonzero(own))
            return
        a, b = el[below], el[~below]
        in_a, in_b = nodes_of(a, own), nodes_of(b, own)
        sep = in_a & in_b
        split(a, in_a & ~sep)
        split(b, in_b & ~sep)
        parts.append(np.flatnonzero(sep))

    split(np.arange(elements.shape[0]), np.ones(n, dtype=bool))
    return np.concatenate(parts)        # lowest_modes checks it is a permutation


@blas_limited
def lowest_modes(K: sp.spmatrix, M: sp.spmatrix, free: np.ndarray,
                 n_modes: int, node_order: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Lowest eigenpairs of ``K x = w^2 M x`` with the DOFs not in ``free`` fixed at 0.

    Shift-invert Lanczos about 0; the fixed DOFs must make K positive definite,
    so its sparse LU takes diagonal pivots (symmetric mode, no row pivoting).
    ``node_order`` (a permutation of the nodes, :func:`nested_dissection`): the DOFs
    are eliminated node by node in that order (three DOFs a node), else in SuperLU's
    own ``LU_ORDERING``; the same eigenpairs (the Lanczos start vector is permuted
    with them), to rounding.

    Returns
    -------
    w2 : ndarray, shape (n_modes,)
        Eigenvalues, ascending.
    X : ndarray, shape (3N, n_modes)
        Mass-normalized eigenvectors (``X^T M X = I``), zero at fixed DOFs; each
        scaled so that its largest-magnitude entry is positive.
    """
    idx = np.flatnonzero(free)
    v0 = np.random.default_rng(EIGEN_SEED).standard_normal(len(idx))
    spec = LU_ORDERING
    if node_order is not None:
        # the free DOFs in the nodes' order: their positions among the free DOFs
        where = np.full(K.shape[0], -1, dtype=np.int64)
        where[idx] = np.arange(len(idx))
        nodes = np.asarray(node_order)
        every = np.arange(K.shape[0] // 3)
        if not (nodes.ndim == 1 and np.array_equal(np.sort(nodes), every)):
            raise ValueError(f"node_order: expected a permutation of the {K.shape[0] // 3} "
                             f"nodes, got {nodes.size} entries")
        dofs = (nodes.astype(np.int64)[:, None] * 3 + np.arange(3)).ravel()
        perm = where[dofs]
        perm = perm[perm >= 0]
        idx, v0, spec = idx[perm], v0[perm], "NATURAL"
    Kc = K[idx][:, idx].tocsc()
    Mc = M[idx][:, idx].tocsc()
    lu = splu(Kc, permc_spec=spec, diag_pivot_thresh=0.0,
              options={"SymmetricMode": True})
    op = LinearOperator(Kc.shape, matvec=lu.solve, dtype=float)
    w2, Xc = eigsh(Kc, k=n_modes, M=Mc, sigma=0.0, which="LM", OPinv=op, v0=v0,
                   tol=EIGEN_TOL, ncv=min(len(idx), max(2 * n_modes + 1, 20)))
    order = np.argsort(w2)
    w2, Xc = w2[order], Xc[:, order]
    Xc = Xc / np.sqrt(np.einsum("ik,ik->k", Xc, Mc @ Xc))
    X = np.zeros((K.shape[0], n_modes))
    X[idx] = Xc
    # the sign from the largest entry in DOF order (the first of equals), whatever the
    # elimination order
    big = np.argmax(np.abs(X), axis=0)
    return w2, X * np.sign(X[big, np.arange(n_modes)])
