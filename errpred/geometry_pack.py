"""Compact, exact pickled form of a prediction point's per-revolution arrays.

Stage 1's results (:class:`errpred.geometry.PointGeometry`) go from the
workers (Dask or forked) to the parent pickled. Flute 0's engagement over a
revolution, ``(cutting0, weight0, shift0)`` each (n, m), is almost all zero:
a few hundred cells of tens of thousands. Here it is packed as the runs of
its non-zero cells (flat C order), the weights as counts of the
``ENGAGEMENT_SUBSTEPS * ENGAGEMENT_SUBEDGES`` sub-samples (one byte each),
the centroid offsets only where they are non-zero (they lie on the weights'
cells), and ``cutting0`` not at all where it is ``weight0 > 0`` (as
:meth:`errpred.point_engagement.PointEngagement.engagement` returns it).

Every unpacked array is bit for bit the packed one (dtype, shape, bytes): a
value is non-zero by its bits (``-0.0`` is kept), and whatever breaks an
assumption (a weight that is not an exact count, an offset off the weights'
cells, ``cutting0`` other than ``weight0 > 0``, another dtype or shape) is
packed by :func:`pack_sparse` (non-zero runs and their values, any dtype) or
left as it is (an object array, or one the runs would not make smaller).
"""

from __future__ import annotations

import math

import numpy as np

from . import constants as K

__all__ = ["pack_sparse", "unpack_sparse", "pack_engagement", "unpack_engagement"]

#: Sub-samples of a boundary cell: a weight is a count of them over this [-].
SUB_SAMPLES = K.ENGAGEMENT_SUBSTEPS * K.ENGAGEMENT_SUBEDGES

_SPARSE = "sparse"          # (tag, shape, dtype, runs, values): any array
_COUNTS = "counts"          # (tag, shape, denominator, runs, counts): float32 weights
_ON_WEIGHT = "on-weight"    # (tag, bits, values): float32 offsets on the weights' cells
_DERIVED = "weight>0"       # cutting0 is weight0 > 0


def _index_dtype(size: int) -> type:
    return np.int32 if size < 2**31 else np.int64


def _nonzero_bits(flat: np.ndarray) -> np.ndarray:
    """Indices of the entries of a 1-d contiguous array whose bits are not all 0."""
    size = flat.dtype.itemsize
    if size in (1, 2, 4, 8):  # (numpy's nonzero is quickest on bools)
        return np.flatnonzero(flat.view(f"u{size}") != 0)
    return np.flatnonzero(flat.view(np.uint8).reshape(flat.size, size).any(axis=1))


def _runs(idx: np.ndarray, size: int) -> bytes:
    """Ascending indices as their runs of consecutive values: starts then lengths."""
    it = _index_dtype(size)
    if idx.size == 0:
        return b""
    brk = np.flatnonzero(np.diff(idx) != 1) + 1
    starts = idx[np.concatenate(([0], brk))]
    ends = np.concatenate((idx[brk - 1], idx[-1:])) + 1
    return np.concatenate((starts, ends - starts)).astype(it).tobytes()


def _indices(runs: bytes, size: int) -> np.ndarray:
    """The indices of :func:`_runs`."""
    se = np.frombuffer(runs, dtype=_index_dtype(size)).astype(np.intp)
    k = se.size // 2
    starts, lengths = se[:k], se[k:]
    ends = np.cumsum(lengths)
    offset = starts - (ends - lengths)
    return np.repeat(offset, lengths) + np.arange(int(ends[-1]) if k else 0)


def pack_sparse(a):
    """``a`` (any array, or anything else) in a form that pickles smaller, exactly.

    An array (not of objects) whose non-zero entries (by their bits) and their
    runs take fewer bytes than the array becomes ``("sparse", shape, dtype,
    runs, values)``; anything else is returned as it is. :func:`unpack_sparse`
    gives it back.
    """
    if not isinstance(a, np.ndarray) or a.dtype.hasobject or a.dtype.itemsize == 0:
        return a
    flat = a.reshape(-1)
    if not flat.flags.c_contiguous:
        flat = np.ascontiguousarray(flat)
    idx = _nonzero_bits(flat)
    runs = _runs(idx, flat.size)
    if len(runs) + idx.size * a.dtype.itemsize >= a.nbytes:
        return a
    dtype = a.dtype.str if np.dtype(a.dtype.str) == a.dtype else a.dtype
    return (_SPARSE, a.shape, dtype, runs, flat[idx].tobytes())


def unpack_sparse(p):
    """The array :func:`pack_sparse` packed (anything else as it is)."""
    if not (isinstance(p, tuple) and len(p) == 5 and p[0] == _SPARSE):
        return p
    _, shape, dtype, runs, values = p
    dtype = np.dtype(dtype)
    size = math.prod(shape)
    out = np.zeros(size, dtype=dtype)
    out[_indices(runs, size)] = np.frombuffer(values, dtype=dtype)
    return out.reshape(shape)


def _pack_weight(weight) -> tuple[object, np.ndarray | None]:
    """``weight`` as counts of sub-samples where every non-zero entry is one exactly
    (with the flat indices of its non-zero entries), else :func:`pack_sparse`'s form
    (and None)."""
    if not isinstance(weight, np.ndarray) or weight.dtype != np.float32 or not weight.size:
        return pack_sparse(weight), None
    flat = np.ascontiguousarray(weight.reshape(-1))
    idx = _nonzero_bits(flat)
    w = flat[idx]
    c = w * np.float32(SUB_SAMPLES)
    cdt = np.uint8 if SUB_SAMPLES <= 255 else np.uint16
    if not (np.all(c >= 1) and np.all(c <= SUB_SAMPLES)):
        return pack_sparse(weight), None
    counts = c.astype(cdt)
    # exact only if unpacking gives every bit back (NaN, -0.0 and the rest fail here)
    if not np.array_equal(_weights(counts, SUB_SAMPLES).view(np.uint32), w.view(np.uint32)):
        return pack_sparse(weight), None
    return (_COUNTS, weight.shape, SUB_SAMPLES, _runs(idx, flat.size), counts.tobytes()), idx


def _weights(counts: np.ndarray, denominator: int) -> np.ndarray:
    return counts.astype(np.float32) / np.float32(denominator)


def pack_engagement(cutting, weight, shift) -> tuple:
    """``(cutting0, weight0, shift0)`` of an engagement (arrays (n, m) or None) in a
    form that pickles small, exactly (:func:`unpack_engagement` gives them back).

    ``weight`` float32, every non-zero entry a count over ``SUB_SAMPLES``: the runs
    of its non-zero cells and one byte a cell; ``shift`` float32 of the same
    shape, non-zero only on those cells: a bit and, where set, its value a cell;
    ``cutting`` bool equal to ``weight > 0``: nothing. Each other case packed by
    :func:`pack_sparse` on its own.
    """
    wp, idx = _pack_weight(weight)
    sp = None
    if (idx is not None and isinstance(shift, np.ndarray) and shift.dtype == np.float32
            and shift.shape == weight.shape):
        flat = np.ascontiguousarray(shift.reshape(-1))
        on = flat.view(np.uint32)[idx] != 0
        if np.count_nonzero(on) == np.count_nonzero(flat.view(np.uint32)):
            sp = (_ON_WEIGHT, np.packbits(on).tobytes(), flat[idx[on]].tobytes())
    if sp is None:
        sp = pack_sparse(shift)
    if (isinstance(cutting, np.ndarray) and isinstance(weight, np.ndarray)
            and cutting.dtype == np.bool_ and cutting.shape == weight.shape
            and weight.dtype.kind == "f"
            and np.array_equal(cutting.view(np.uint8), (weight > 0).view(np.uint8))):
        cp = _DERIVED
    else:
        cp = pack_sparse(cutting)
    return (cp, wp, sp)


def unpack_engagement(p: tuple) -> tuple:
    """``(cutting0, weight0, shift0)`` as :func:`pack_engagement` packed them."""
    cp, wp, sp = p
    idx = None
    if isinstance(wp, tuple) and len(wp) == 5 and wp[0] == _COUNTS:
        _, shape, denominator, runs, counts = wp
        size = math.prod(shape)
        idx = _indices(runs, size)
        cdt = np.uint8 if denominator <= 255 else np.uint16
        weight = np.zeros(size, dtype=np.float32)
        weight[idx] = _weights(np.frombuffer(counts, dtype=cdt), denominator)
        weight = weight.reshape(shape)
    else:
        weight = unpack_sparse(wp)
    if isinstance(sp, tuple) and len(sp) == 3 and sp[0] == _ON_WEIGHT:
        _, bits, values = sp
        on = np.unpackbits(np.frombuffer(bits, dtype=np.uint8), count=idx.size).view(bool)
        shift = np.zeros(weight.size, dtype=np.float32)
        shift[idx[on]] = np.frombuffer(values, dtype=np.float32)
        shift = shift.reshape(weight.shape)
    else:
        shift = unpack_sparse(sp)
    if isinstance(cp, str) and cp == _DERIVED and idx is not None:
        cutting = np.zeros(weight.size, dtype=bool)   # weight > 0 exactly on idx
        cutting[idx] = True
        cutting = cutting.reshape(weight.shape)
    elif isinstance(cp, str) and cp == _DERIVED:
        cutting = weight > 0
    else:
        cutting = unpack_sparse(cp)
    return cutting, weight, shift
