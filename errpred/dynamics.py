"""Tool-tip compliance and the periodic deflection it gives (``docs/method.md`` §5).

A :class:`Compliance` holds the direct (point) compliance of the tool tip,
``G(omega)`` [m/N], for each direction: ``'x'`` and ``'y'`` are the tool's two
bending directions (world X and Y projected onto the plane normal to the tool
axis), ``'z'`` (optional) the axis. Cross terms are not modelled. It comes
from modal parameters (``G = sum_k 1 / (k_k - m_k omega^2 + i c_k omega)``),
from the static model ``D = C F`` (``G = sum_k 1 / k_k`` at every frequency)
or from a measured FRF (impact test: arrays, UFF type 58, CSV or CutPro ``.frf``
files; the file readers are in :mod:`errpred.frf_files`).

Sign convention: a force ``Re(F e^{i omega t})`` gives the displacement
``Re(G(omega) F e^{i omega t})``; numpy's forward FFT uses ``e^{-i...}``, so
``D = irfft(G rfft(F))`` and a lightly damped mode driven at resonance lags
the force by 90 degrees. ``G(-omega) = conj(G(omega))`` (a real structure).

Only :meth:`Compliance.from_uff`, :meth:`Compliance.from_csv`,
:meth:`Compliance.from_cutpro` and :meth:`Compliance.to_uff` touch files;
everything else is pure computation.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from nc.atomic import atomic_path
from nc.checks import real_number as _real

from .frf_files import DIRECTIONS, FRFDataError, read_frf_csv, read_frf_cutpro, read_uff_record
from .spindle import tooth_frequency

__all__ = ["DIRECTIONS", "Compliance", "FRFDataError", "Mode", "receptance"]

_UFF_DIR = {"x": 1, "y": 2, "z": 3}


def receptance(k_N_m, m_kg, c_Ns_m, omega_rad_s):
    """A single-DOF mode's ``1 / (k - m omega^2 + i c omega)`` [m/N], broadcast over
    its arguments (the modal sum of :meth:`Compliance.response`; stage 2's workpiece
    modes, :func:`errpred.physics._deflection`)."""
    w = omega_rad_s
    return 1.0 / (k_N_m - m_kg * w * w + 1j * c_Ns_m * w)


@dataclass(frozen=True)
class Mode:
    """One mode of the tool tip in one direction.

    Attributes
    ----------
    k_N_m : float
        Modal stiffness [N/m], > 0.
    m_kg : float
        Modal mass [kg], > 0.
    c_Ns_m : float
        Modal (viscous) damping [N s/m], >= 0.
    """

    k_N_m: float
    m_kg: float
    c_Ns_m: float

    def __post_init__(self) -> None:
        for name, bound in (("k_N_m", ">0"), ("m_kg", ">0"), ("c_Ns_m", ">=0")):
            object.__setattr__(self, name, _real(f"Mode.{name}", getattr(self, name), bound))

    @classmethod
    def from_frequency(cls, f_hz: float, zeta: float, k_N_m: float) -> Mode:
        """Mode from natural frequency ``f_hz`` [Hz] (> 0), damping ratio ``zeta``
        [-] (>= 0) and stiffness ``k_N_m`` [N/m]: ``m = k / omega_n^2``,
        ``c = 2 zeta sqrt(k m)``."""
        f = _real("Mode.from_frequency: f_hz", f_hz, ">0")
        z = _real("Mode.from_frequency: zeta", zeta, ">=0")
        k = _real("Mode.from_frequency: k_N_m", k_N_m, ">0")
        m = k / (2.0 * math.pi * f) ** 2
        return cls(k, m, 2.0 * z * math.sqrt(k * m))

    @property
    def natural_frequency_hz(self) -> float:
        """Undamped natural frequency ``sqrt(k/m) / 2 pi`` [Hz]."""
        return math.sqrt(self.k_N_m / self.m_kg) / (2.0 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """Damping ratio ``c / (2 sqrt(k m))`` [-]."""
        return self.c_Ns_m / (2.0 * math.sqrt(self.k_N_m * self.m_kg))


def _check_directions(keys: Any, where: str) -> tuple[str, ...]:
    keys = list(keys)
    bad = [k for k in keys if k not in DIRECTIONS]
    if bad or not keys:
        raise ValueError(f"{where}: directions must be a non-empty subset of {DIRECTIONS}, "
                         f"got {keys!r}")
    return tuple(d for d in DIRECTIONS if d in keys)


class Compliance:
    """Direct tool-tip compliance ``G(omega)`` [m/N] per direction.

    Build it with :meth:`from_modes`, :meth:`from_frf`, :meth:`from_uff`,
    :meth:`from_csv` or :meth:`from_cutpro`. Columns of :meth:`response` and
    of the force and deflection arrays of :meth:`deflection` follow
    :attr:`directions` (``'x'``, ``'y'``, ``'z'`` order, those present).

    Measured FRFs are evaluated by linear interpolation of the real and the
    imaginary parts between measured frequencies. Below the first measured
    frequency ``f0``: a linear blend from the static compliance at 0 Hz to
    ``G(f0)`` when a static value is given, else ``G(f0)`` held (a note is
    recorded in :attr:`notes`). Above the last measured frequency ``fL``:
    ``G(f) = G(fL) (fL / f)^2``. Above its modes a structure follows its mass
    line, ``G ~ -1 / (m omega^2)``; scaling the last measured value by
    ``1/omega^2`` is continuous at ``fL`` and decays like that line (exact when
    the last point already lies on the mass line; it cannot know of modes
    above the band). Measure past the highest harmonic that matters.
    """

    __slots__ = ("_dirs", "_freq", "_frf", "_kind", "_modes", "_notes", "_static")

    def __init__(self, *, _kind: str, _dirs: tuple[str, ...], _modes=None, _freq=None,
                 _frf=None, _static=None, _notes: Sequence[str] = ()) -> None:
        # Private: use the from_* constructors.
        self._kind, self._dirs, self._modes = _kind, _dirs, _modes
        self._freq, self._frf, self._static = _freq, _frf, _static
        self._notes = tuple(_notes)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_modes(cls, modes: Mapping[str, Sequence[Mode] | Mode], *,
                   static_only: bool = False) -> Compliance:
        """Compliance from modal parameters.

        Parameters
        ----------
        modes : mapping of str to sequence of Mode
            Modes per direction (``'x'``, ``'y'``, optionally ``'z'``); at least
            one mode per direction given.
        static_only : bool
            If True, the static model: ``G(omega) = G(0) = sum_k 1 / k_k``
            [m/N] at every frequency (``D = C F``, no dynamics, no phase lag).
        """
        dirs = _check_directions(modes.keys(), "Compliance.from_modes")
        table = {}
        for d in dirs:
            ms = modes[d]
            ms = (ms,) if isinstance(ms, Mode) else tuple(ms)
            if not ms or not all(isinstance(m, Mode) for m in ms):
                raise ValueError(f"Compliance.from_modes: direction {d!r}: expected one or "
                                 f"more Mode objects, got {modes[d]!r}")
            table[d] = ms
        return cls(_kind="static" if static_only else "modal", _dirs=dirs, _modes=table)

    @classmethod
    def from_frf(cls, freq_hz: Any, frf_m_N: Mapping[str, Any],
                 static_m_N: Mapping[str, float] | None = None, *,
                 notes: Sequence[str] = ()) -> Compliance:
        """Compliance from a measured FRF.

        Parameters
        ----------
        freq_hz : array_like, shape (n,), or mapping of str to array_like
            Measured frequencies [Hz]: finite, >= 0, strictly increasing, at
            least 2. One array for all directions, or one per direction.
        frf_m_N : mapping of str to array_like complex, shape (n,)
            Direct receptance per direction [m/N].
        static_m_N : mapping of str to float, optional
            Static compliance G(0) per direction [m/N] (e.g. from a static
            stiffness test), used below the first measured frequency. Directions
            left out hold the first measured value (noted in :attr:`notes`).
        notes : sequence of str
            Notes to carry (used by the file readers).
        """
        dirs = _check_directions(frf_m_N.keys(), "Compliance.from_frf")
        static = dict(static_m_N or {})
        extra = set(static) - set(dirs)
        if extra:
            raise ValueError(f"Compliance.from_frf: static_m_N has directions {sorted(extra)} "
                             f"without an FRF")
        freq, frf, st, out_notes = {}, {}, {}, list(notes)
        for d in dirs:
            f = freq_hz[d] if isinstance(freq_hz, Mapping) else freq_hz
            f = np.asarray(f, dtype=float)
            g = np.asarray(frf_m_N[d], dtype=complex)
            where = f"Compliance.from_frf: direction {d!r}"
            if f.ndim != 1 or f.size < 2 or g.shape != f.shape:
                raise ValueError(f"{where}: need 1-D frequency and FRF arrays of equal length "
                                 f">= 2, got shapes {f.shape} and {g.shape}")
            if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
                i = int(np.flatnonzero(~(np.isfinite(f) & np.isfinite(g)))[0])
                raise ValueError(f"{where}: non-finite value at point {i}")
            if f[0] < 0 or np.any(np.diff(f) <= 0):
                raise ValueError(f"{where}: frequencies must be >= 0 and strictly increasing")
            freq[d], frf[d] = f.copy(), g.copy()
            if d in static:
                s = _real(f"Compliance.from_frf: static_m_N[{d!r}]", static[d], ">0")
                if f[0] == 0:
                    out_notes.append(f"{d}: FRF measured at 0 Hz; static_m_N ignored")
                else:
                    st[d] = s
            elif f[0] > 0:
                out_notes.append(f"{d}: no static compliance; the FRF value at {f[0]:g} Hz "
                                 f"is held down to 0 Hz (mean-force deflection may be wrong)")
        return cls(_kind="measured", _dirs=dirs, _freq=freq, _frf=frf, _static=st,
                   _notes=out_notes)

    @classmethod
    def from_uff(cls, path: str | os.PathLike, directions: Mapping[str, int] | None = None, *,
                 static_m_N: Mapping[str, float] | None = None) -> Compliance:
        """Read direct FRFs from a universal file (UFF type 58 records), with pyuff.

        Parameters
        ----------
        path : path-like
            The ``.uff``/``.unv`` file (ASCII or binary type 58).
        directions : mapping of str to int, optional
            Explicit mapping ``{'x': record_index, 'y': record_index, ...}``;
            indices count all records in the file from 0 (as pyuff does).
            Overrides the DOF fields. If omitted, records are mapped by their
            DOF fields: response direction +-1/2/3 is x/y/z; the reference
            direction must be the same axis (a direct FRF) or 0. Records that
            are not FRFs (function type != 4, e.g. coherence), rotational or
            scalar DOFs, or cross FRFs are skipped with a note; two direct FRFs
            for one direction is an error (pass ``directions``).
        static_m_N : mapping, optional
            As in :meth:`from_frf`.

        Notes
        -----
        The FRF is multiplied by ``sign(rsp_dir) sign(ref_dir)`` (a -X/+X
        record becomes +X/+X). Abscissa: Hz (units label ``Hz`` or none;
        ``rad/s`` is converted). Ordinate: receptance (displacement/force,
        spec data type 8, or 0/1 general); the units come from the ordinate
        units labels, either ``m``/``mm``/``um`` (``µm``, ``micron``) over ``N``
        or one label such as ``mm/N``; no label means m/N (noted).
        Velocity or acceleration ordinates (mobility, inertance) are refused:
        convert them to receptance (``G = -A / omega^2``) first.

        Raises
        ------
        FRFDataError (a ValueError)
            Missing or unreadable file, no type-58 records, a selected record
            that is not a complex FRF, non-finite data, unknown units; the
            message names the file and the record index.
        """
        import pyuff

        if not os.path.isfile(path):
            raise FRFDataError("no such file", path=path)
        try:  # one UFF object: pyuff scans the whole file on construction
            uff = pyuff.UFF(os.fspath(path))
            types = [int(t) for t in uff.get_set_types()]
        except Exception as exc:  # pyuff raises bare Exception
            raise FRFDataError(f"not a readable universal file ({exc})", path=path) from exc
        if 58 not in types:
            raise FRFDataError(f"no type-58 (function at nodal DOF) records; record types "
                               f"found: {types}", path=path)
        notes: list[str] = []
        chosen: dict[str, tuple[int, dict]] = {}
        if directions is not None:
            for d in _check_directions(directions.keys(), "Compliance.from_uff"):
                i = directions[d]
                if isinstance(i, bool) or not isinstance(i, numbers.Integral) \
                        or not 0 <= i < len(types) or types[i] != 58:
                    raise FRFDataError(f"direction {d!r}: record {i!r} is not a type-58 record "
                                       f"(record types: {types})", path=path)
                chosen[d] = (int(i), read_uff_record(uff, path, int(i), strict=True))
        else:
            for i in (i for i, t in enumerate(types) if t == 58):
                rec = read_uff_record(uff, path, i, strict=False)
                if isinstance(rec, str):
                    notes.append(f"record {i}: skipped ({rec})")
                elif rec["direction"] in chosen:
                    raise FRFDataError(f"a second direct FRF for direction {rec['direction']!r} "
                                       f"(the first is record {chosen[rec['direction']][0]}); "
                                       f"pass directions= to choose", path=path, record=i)
                else:
                    chosen[rec["direction"]] = (i, rec)
            if not chosen:
                raise FRFDataError("no direct translational FRF (function type 4) among the "
                                   "type-58 records: " + "; ".join(notes), path=path)
        for d, (i, rec) in chosen.items():
            notes += [f"{d} (record {i}): {n}" for n in rec["notes"]]
        return cls.from_frf({d: r["freq_hz"] for d, (_, r) in chosen.items()},
                            {d: r["frf_m_N"] for d, (_, r) in chosen.items()},
                            static_m_N, notes=notes)

    @classmethod
    def from_csv(cls, paths: Mapping[str, str | os.PathLike], *,
                 static_m_N: Mapping[str, float] | None = None) -> Compliance:
        """Read one FRF file per direction.

        Each file has a header line ``frequency_hz,real_m_N,imag_m_N`` (comma or
        tab separated, column order free, extra columns ignored; ``real_mm_N``/
        ``imag_mm_N`` or ``real_um_N``/``imag_um_N`` give mm/N or um/N and are
        converted), then one row per frequency. Blank lines and lines starting
        with ``#`` are skipped. Frequencies in Hz, >= 0, strictly increasing.

        Raises
        ------
        FRFDataError (a ValueError)
            Naming the file, line and column (1-based) of the first bad field.
        """
        dirs = _check_directions(paths.keys(), "Compliance.from_csv")
        freq, frf = {}, {}
        for d in dirs:
            freq[d], frf[d] = read_frf_csv(paths[d])
        return cls.from_frf(freq, frf, static_m_N)

    @classmethod
    def from_cutpro(cls, paths: Mapping[str, str | os.PathLike], *,
                    static_m_N: Mapping[str, float] | None = None) -> Compliance:
        """Read one CutPro ``.frf`` file per direction (``{'x': path, 'y': path}``).

        Each file holds one direct FRF: rows of frequency [Hz], real and
        imaginary receptance [m/N] (see :func:`errpred.frf_files.read_frf_cutpro`
        for what is accepted, and the assumption behind it). ``static_m_N`` as in
        :meth:`from_frf`.

        Raises
        ------
        FRFDataError (a ValueError)
            Naming the file, line and column (1-based) of the first bad field.
        """
        dirs = _check_directions(paths.keys(), "Compliance.from_cutpro")
        freq, frf, notes = {}, {}, []
        for d in dirs:
            freq[d], frf[d], n = read_frf_cutpro(paths[d])
            notes += [f"{d}: {x}" for x in n]
        return cls.from_frf(freq, frf, static_m_N, notes=notes)

    # ------------------------------------------------------------------ properties
    @property
    def directions(self) -> tuple[str, ...]:
        """Direction names, in column order."""
        return self._dirs

    @property
    def kind(self) -> str:
        """``'modal'``, ``'static'`` (static_only) or ``'measured'``."""
        return self._kind

    @property
    def notes(self) -> tuple[str, ...]:
        """Warnings from construction (held values, skipped records, assumed units)."""
        return self._notes

    @property
    def modes(self) -> dict[str, tuple[Mode, ...]]:
        """Modes per direction (empty for a measured FRF)."""
        return dict(self._modes or {})

    @property
    def static_compliance_m_N(self) -> dict[str, float]:
        """``G(0)`` per direction [m/N]: ``sum 1/k`` for modes; for a measured
        FRF the static value, or the real part of the first measured point."""
        g0 = self.response(np.zeros(1))[0]
        return {d: float(g0[j].real) for j, d in enumerate(self._dirs)}

    def __repr__(self) -> str:
        return f"Compliance(kind={self._kind!r}, directions={self._dirs!r})"

    # ------------------------------------------------------------------ evaluation
    def response(self, omega_rad_s: Any) -> np.ndarray:
        """``G(omega)`` [m/N], shape ``omega.shape + (ndir,)`` (``(n, ndir)`` for 1-D).

        Parameters
        ----------
        omega_rad_s : array_like
            Angular frequencies [rad/s], finite; negative ones give ``conj(G(|omega|))``.
        """
        w = np.asarray(omega_rad_s, dtype=float)
        if not np.all(np.isfinite(w)):
            raise ValueError("Compliance.response: omega_rad_s must be finite")
        out = np.empty(w.shape + (len(self._dirs),), dtype=complex)
        for j, d in enumerate(self._dirs):
            if self._kind == "measured":
                g = self._interp(d, np.abs(w) / (2.0 * math.pi))
                out[..., j] = np.where(w < 0, np.conj(g), g)
                continue
            k = np.array([m.k_N_m for m in self._modes[d]])
            if self._kind == "static":
                out[..., j] = np.sum(1.0 / k)
                continue
            m = np.array([m.m_kg for m in self._modes[d]])
            c = np.array([m.c_Ns_m for m in self._modes[d]])
            out[..., j] = np.sum(receptance(k, m, c, w[..., None]), axis=-1)
        return out

    def _interp(self, d: str, f: np.ndarray) -> np.ndarray:
        fr, g = self._freq[d], self._frf[d]
        out = np.interp(f, fr, g.real) + 1j * np.interp(f, fr, g.imag)   # holds g[0] below
        if d in self._static:
            s = self._static[d]
            out = np.where(f < fr[0], s + (g[0] - s) * (f / fr[0]), out)
        hi = f > fr[-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(hi, g[-1] * (fr[-1] / np.where(hi, f, 1.0)) ** 2, out)

    def transfer_functions(self) -> dict:
        """``{direction: control.TransferFunction}`` of the modal compliance [m/N].

        Built with python-control: ``sum_k tf([1], [m_k, c_k, k_k])``; for the
        static model a constant gain ``sum 1/k``. Raises ValueError for a
        measured FRF, which has no rational transfer function (use
        :meth:`response` at ``omega`` instead).
        """
        import control

        if self._kind == "measured":
            raise ValueError("Compliance.transfer_functions: a measured FRF has no transfer "
                             "function; evaluate it with response(omega) or fit modes first")
        tfs = {}
        for d in self._dirs:
            ms = self._modes[d]
            if self._kind == "static":
                tfs[d] = control.tf([sum(1.0 / m.k_N_m for m in ms)], [1.0])
                continue
            parts = [control.tf([1.0], [m.m_kg, m.c_Ns_m, m.k_N_m]) for m in ms]
            tfs[d] = sum(parts[1:], parts[0])
        return tfs

    def deflection(self, force_N: Any, spindle_rpm: float) -> np.ndarray:
        """Periodic steady-state deflection of the tool tip over one revolution [mm].

        Parameters
        ----------
        force_N : array_like, shape (..., n, ndir)
            Force on the tool [N], columns in :attr:`directions` order, sampled
            at ``n`` equal steps of the rotation angle over one revolution
            (``n`` even, >= 4; sample ``i`` at angle ``2 pi i / n``).
        spindle_rpm : float
            Spindle speed [rev/min], finite and > 0.

        Returns
        -------
        ndarray, shape (..., n, ndir)
            ``D = irfft(G(omega_m) rfft(F)) * 1000`` [mm], ``omega_m = 2 pi m S / 60``
            for harmonic ``m = 0 .. n/2`` of the spindle frequency. The Nyquist
            harmonic is taken as a cosine (its response ``Re(G) F``, which is
            what a sampled cosine shows), the mean force sees ``Re G(0)``.
        """
        f = np.asarray(force_N, dtype=float)
        ndir = len(self._dirs)
        if f.ndim < 2 or f.shape[-1] != ndir:
            raise ValueError(f"Compliance.deflection: force_N must have shape (..., n, {ndir}) "
                             f"for directions {self._dirs}, got {f.shape}")
        n = f.shape[-2]
        if n < 4 or n % 2:
            raise ValueError(f"Compliance.deflection: need an even number >= 4 of samples per "
                             f"revolution, got n = {n}")
        if not np.all(np.isfinite(f)):
            raise ValueError("Compliance.deflection: force_N has non-finite values")
        rpm = _real("Compliance.deflection: spindle_rpm", spindle_rpm, ">0")
        omega = 2.0 * math.pi * tooth_frequency(rpm) * np.arange(n // 2 + 1)
        spec = np.fft.rfft(f, axis=-2) * self.response(omega)
        return np.fft.irfft(spec, n=n, axis=-2) * 1000.0

    # ------------------------------------------------------------------ writer
    def to_uff(self, path: str | os.PathLike, freq_hz: Any = None) -> None:
        """Write the compliance as UFF type 58 FRF records (one per direction), atomically.

        Parameters
        ----------
        path : path-like
            Target file; written to a temporary file in the same directory and
            renamed onto ``path``.
        freq_hz : array_like, optional
            Frequencies [Hz] (>= 0, strictly increasing, >= 2). Required for a
            modal compliance; a measured one defaults to its own grids.

        Notes
        -----
        ASCII, complex double, uneven abscissa; response and reference DOF
        node 1, directions +1/+2/+3 for x/y/z; units labels ``m`` over ``N``,
        abscissa ``Hz``. The format keeps 6 significant digits of each
        frequency (E13.5) and 12 of each FRF value (E20.12).
        """
        import pyuff

        if freq_hz is None and self._kind != "measured":
            raise ValueError("Compliance.to_uff: freq_hz is required for a modal compliance")
        sets = []
        for j, d in enumerate(self._dirs):
            f = np.asarray(self._freq[d] if freq_hz is None else freq_hz, dtype=float)
            if f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f)) or f[0] < 0 \
                    or np.any(np.diff(f) <= 0):
                raise ValueError("Compliance.to_uff: freq_hz must be 1-D, finite, >= 0, "
                                 "strictly increasing, with at least 2 points")
            g = self.response(2.0 * math.pi * f)[:, j]
            sets.append(pyuff.prepare_58(
                binary=0, id1=f"tool-tip compliance {d}", id2="errpred.dynamics",
                func_type=4, rsp_node=1, rsp_dir=_UFF_DIR[d], ref_node=1, ref_dir=_UFF_DIR[d],
                abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz",
                ordinate_spec_data_type=8, ordinate_axis_units_lab="m",
                orddenom_spec_data_type=13, orddenom_axis_units_lab="N", data=g, x=f))
        with atomic_path(path) as tmp:
            # pyuff writes by file name; 'add' to the fresh empty file
            pyuff.UFF(tmp).write_sets(sets, mode="add")
