"""FRF files: the readers behind :class:`errpred.dynamics.Compliance`'s file constructors.

Three formats of a measured direct (point) FRF of the tool tip, receptance
in m/N against frequency in Hz:

* universal file type 58 records (:func:`read_uff_record`, on a ``pyuff.UFF``);
* CSV with a header ``frequency_hz,real_m_N,imag_m_N`` (:func:`read_frf_csv`);
* CutPro ``.frf`` text (:func:`read_frf_cutpro`).

Every problem raises :class:`FRFDataError` naming the file and the record or
line (and column). Pure reading: the arrays go to ``Compliance.from_frf``,
which checks them again and owns the interpolation.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from nc.errors import InputError

__all__ = ["DIRECTIONS", "FRFDataError", "read_frf_csv", "read_frf_cutpro", "read_uff_record"]

#: Allowed direction names, in the column order used everywhere.
DIRECTIONS = ("x", "y", "z")
#: Length units accepted for FRF ordinates, as factors to metres.
_LENGTH_M = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "micron": 1e-6, "microns": 1e-6}


class FRFDataError(InputError):
    """Bad FRF input. Attributes ``path``, ``record``, ``line``, ``column``
    (None where not applicable) locate the problem; the message names them."""

    def __init__(self, message: str, *, path: Any = None, record: int | None = None,
                 line: int | None = None, column: int | None = None) -> None:
        where = [] if path is None else [os.fspath(path)]
        where += [f"{k} {v}" for k, v in (("record", record), ("line", line), ("column", column))
                  if v is not None]
        super().__init__(f"{', '.join(where)}: {message}" if where else message)
        self.path, self.record, self.line, self.column = path, record, line, column


# ---------------------------------------------------------------------- file readers
def _uff_units(rec: dict, path: Any, i: int) -> tuple[float, list[str]]:
    """Factor from the record's ordinate units to m/N."""
    num = str(rec.get("ordinate_axis_units_lab", "") or "").strip()
    den = str(rec.get("orddenom_axis_units_lab", "") or "").strip()
    num = "" if num.upper() == "NONE" else num
    den = "" if den.upper() == "NONE" else den
    if "/" in num:
        num, _, den2 = num.partition("/")
        den = den or den2
    if not num:
        if den.lower() not in ("n", ""):
            raise FRFDataError(f"ordinate denominator units {den!r}; expected N", path=path,
                               record=i)
        return 1.0, ["no ordinate units label; m/N assumed"]
    fac = _LENGTH_M.get(num.strip().lower().replace("µ", "u").replace("μ", "u"))
    if fac is None or den.strip().lower() not in ("n", ""):
        raise FRFDataError(f"ordinate units {num!r}/{den!r} not understood; expected "
                           f"m, mm or um per N", path=path, record=i)
    return fac, []


def read_uff_record(uff: Any, path: Any, i: int, *, strict: bool) -> dict | str:
    """Read and check record ``i`` of the ``pyuff.UFF`` object. Returns a dict, or
    (``strict=False``) a reason string for a record that is not a direct
    translational FRF."""
    try:
        rec = uff.read_sets(i)
    except Exception as exc:
        raise FRFDataError(f"cannot read the record ({exc})", path=path, record=i) from exc
    ft = int(rec.get("func_type", -1))
    if ft != 4:
        if not strict:
            return f"function type {ft}, not 4 (FRF)"
        raise FRFDataError(f"function type {ft}, not 4 (frequency response function)",
                           path=path, record=i)
    rsp, ref = int(rec.get("rsp_dir", 0)), int(rec.get("ref_dir", 0))
    notes: list[str] = []
    if not strict:
        if abs(rsp) not in (1, 2, 3):
            return f"response direction {rsp} is not a translation"
        if ref != 0 and abs(ref) != abs(rsp):
            return f"cross FRF (response direction {rsp}, reference {ref})"
        if ref == 0:
            notes.append("reference direction 0 taken as the response direction")
    sign = -1.0 if rsp * ref < 0 and abs(rsp) in (1, 2, 3) and abs(ref) in (1, 2, 3) else 1.0
    spec = int(rec.get("ordinate_spec_data_type", 0))
    if spec in (11, 12):
        raise FRFDataError(f"ordinate is {'velocity' if spec == 11 else 'acceleration'} "
                           f"(spec data type {spec}); convert to receptance (displacement/"
                           f"force) first", path=path, record=i)
    if int(rec.get("abscissa_spec_data_type", 18)) not in (0, 1, 18):
        raise FRFDataError(f"abscissa spec data type {rec['abscissa_spec_data_type']} is not "
                           f"frequency", path=path, record=i)
    xu = str(rec.get("abscissa_axis_units_lab", "") or "").strip().lower()
    if xu in ("", "none", "hz"):
        xfac = 1.0
    elif xu in ("rad/s", "rad/sec"):
        xfac = 1.0 / (2.0 * math.pi)
    else:
        raise FRFDataError(f"abscissa units {xu!r}; expected Hz", path=path, record=i)
    x, data = rec.get("x"), rec.get("data")
    if x is None or data is None or not np.iscomplexobj(data):
        raise FRFDataError("ordinate is not complex (an FRF needs real and imaginary parts)",
                           path=path, record=i)
    x = np.asarray(x, dtype=float) * xfac
    data = np.asarray(data, dtype=complex)
    bad = ~(np.isfinite(x) & np.isfinite(data))
    if np.any(bad):
        raise FRFDataError(f"non-finite value at point {int(np.flatnonzero(bad)[0])}",
                           path=path, record=i)
    if x.size < 2 or x[0] < 0 or np.any(np.diff(x) <= 0):
        raise FRFDataError("need >= 2 frequencies, >= 0 and strictly increasing",
                           path=path, record=i)
    fac, unotes = _uff_units(rec, path, i)
    return {"direction": DIRECTIONS[abs(rsp) - 1] if abs(rsp) in (1, 2, 3) else None,
            "freq_hz": x, "frf_m_N": data * (sign * fac), "notes": notes + unotes}


def _text_lines(path: Any) -> list[str]:
    """The lines of a text FRF file (a byte-order mark dropped); a file that is
    missing or not text is an :class:`FRFDataError` naming it."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            return fh.read().splitlines()
    except FileNotFoundError as exc:
        raise FRFDataError("no such file", path=path) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise FRFDataError(f"cannot read ({exc})", path=path) from exc


def read_frf_csv(path: Any) -> tuple[np.ndarray, np.ndarray]:
    """Read one ``frequency_hz,real_m_N,imag_m_N`` file; returns (f [Hz], G [m/N])."""
    lines = _text_lines(path)
    header, sep, cols, fac = None, ",", {}, 1.0
    rows: list[tuple[float, float, float]] = []
    for ln, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        if header is None:
            sep = "\t" if "\t" in text else ","
            header = [h.strip() for h in text.split(sep)]
            low = [h.lower() for h in header]
            units = [u for u in ("m", "mm", "um") if f"real_{u}_n" in low and f"imag_{u}_n" in low]
            if "frequency_hz" not in low or not units:
                hint = (" (a CutPro .frf file? read it with Compliance.from_cutpro, "
                        "scenario key dynamics.frf_cutpro)"
                        if os.fspath(path).lower().endswith(".frf") else "")
                raise FRFDataError(f"expected a header 'frequency_hz,real_m_N,imag_m_N' (comma "
                                   f"or tab separated), found {text!r}{hint}", path=path, line=ln)
            fac = _LENGTH_M[units[0]]
            cols = {name: low.index(name) for name in
                    ("frequency_hz", f"real_{units[0]}_n", f"imag_{units[0]}_n")}
            continue
        fields = text.split(sep)
        if len(fields) > len(header):
            raise FRFDataError(f"{len(fields)} fields, the header has {len(header)}",
                               path=path, line=ln, column=len(header) + 1)
        vals = []
        for c in cols.values():
            if c >= len(fields) or not fields[c].strip():
                raise FRFDataError(f"missing value for {header[c]!r}", path=path, line=ln,
                                   column=c + 1)
            try:
                v = float(fields[c].strip())
            except ValueError:
                raise FRFDataError(f"{header[c]}: {fields[c].strip()!r} is not a number",
                                   path=path, line=ln, column=c + 1) from None
            if not math.isfinite(v):
                raise FRFDataError(f"{header[c]}: {fields[c].strip()!r} is not finite",
                                   path=path, line=ln, column=c + 1)
            vals.append(v)
        if vals[0] < 0 or (rows and vals[0] <= rows[-1][0]):
            raise FRFDataError(f"frequency {vals[0]!r} Hz: frequencies must be >= 0 and "
                               f"strictly increasing", path=path, line=ln,
                               column=cols["frequency_hz"] + 1)
        rows.append((vals[0], vals[1], vals[2]))
    if header is None or len(rows) < 2:
        raise FRFDataError(f"need a header and at least 2 data rows, found "
                           f"{'no header' if header is None else f'{len(rows)} rows'}", path=path)
    a = np.array(rows)
    return a[:, 0], (a[:, 1] + 1j * a[:, 2]) * fac


#: Unit labels of a CutPro file's header or label fields, as factors to m/N.
_CUTPRO_UNITS = {f"{u}/n": fac for u, fac in _LENGTH_M.items()}


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def read_frf_cutpro(path: Any) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Read one CutPro ``.frf`` file; returns (f [Hz], G [m/N], notes).

    No published specification of the format was found. This reader follows a
    public MATLAB exporter for CutPro: one row per frequency, three
    tab-separated numbers (frequency [Hz], real and imaginary receptance
    [m/N]), the first row followed by the unit labels ``Freq Hz Real m/N Imag
    Real``. Accepted beyond that: fields separated by tabs or spaces, a
    trailing separator, and a header block of lines that do not start with a
    number before the first row. A unit label ``m/N``, ``mm/N`` or ``um/N``
    (in the header or the first row's labels; also in brackets, ``(m/N)``)
    scales the values; without one
    m/N is assumed (noted). Frequencies >= 0 and strictly increasing; at least
    two rows.

    Raises
    ------
    FRFDataError
        Naming the file, line and column (1-based) of the first bad field.
    """
    lines = _text_lines(path)
    rows: list[tuple[float, float, float]] = []
    labels: list[tuple[int, str]] = []
    for ln, raw in enumerate(lines, start=1):
        fields = raw.split()
        if not fields:
            continue
        if _number(fields[0]) is None:
            if rows:
                raise FRFDataError(f"expected three numbers (frequency [Hz], real, imaginary), "
                                   f"found {raw.strip()!r}", path=path, line=ln, column=1)
            labels += [(ln, f) for f in fields]          # the header block
            continue
        if len(fields) < 3:
            raise FRFDataError(f"{len(fields)} fields; expected three (frequency [Hz], real, "
                               f"imaginary)", path=path, line=ln, column=len(fields) + 1)
        vals = []
        for c, (name, text) in enumerate(zip(("frequency", "real", "imaginary"), fields), 1):
            v = _number(text)
            if v is None or not math.isfinite(v):
                raise FRFDataError(f"{name}: {text!r} is not a finite number", path=path,
                                   line=ln, column=c)
            vals.append(v)
        for c, text in enumerate(fields[3:], start=4):
            if _number(text) is not None or rows:
                extra = "" if rows else " and, on the first row, unit labels"
                raise FRFDataError(f"{len(fields)} fields; expected three (frequency [Hz], real, "
                                   f"imaginary){extra}", path=path, line=ln, column=c)
            labels.append((ln, text))
        if vals[0] < 0 or (rows and vals[0] <= rows[-1][0]):
            raise FRFDataError(f"frequency {vals[0]!r} Hz: frequencies must be >= 0 and "
                               f"strictly increasing", path=path, line=ln, column=1)
        rows.append((vals[0], vals[1], vals[2]))
    if len(rows) < 2:
        raise FRFDataError(f"need at least 2 rows of frequency, real, imaginary; found "
                           f"{len(rows)}", path=path)
    units = {}
    for ln, text in labels:
        key = text.strip("()[]{}").lower().replace("µ", "u").replace("μ", "u")
        if key in _CUTPRO_UNITS:
            units.setdefault(key, ln)
        elif key in ("rad/s", "rad/sec"):
            raise FRFDataError("frequency in rad/s; expected Hz", path=path, line=ln)
    if len(units) > 1:
        raise FRFDataError(f"unit labels disagree: {', '.join(units)}", path=path,
                           line=max(units.values()))
    notes = [] if units else [f"{os.fspath(path)}: no unit label; m/N assumed"]
    fac = _CUTPRO_UNITS[next(iter(units))] if units else 1.0
    a = np.array(rows)
    return a[:, 0], (a[:, 1] + 1j * a[:, 2]) * fac, notes
