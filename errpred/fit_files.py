"""Files of ``python -m errpred fit``: the tests' CSV in, the ``[cutting]`` table out.

The CSV (comma separated, one header row, ``#`` lines are comments)::

    fz_mm,ap_mm,ae_mm,mode,diameter_mm,teeth,rpm,Fx_N,Fy_N,Fz_N
    0.05,2.0,slot,slot,10.0,3,3000,-98.1,206.4,-51.0
    0.10,2.0,3.0,down,10.0,3,3000,-160.2,250.3,-60.1

``fz_mm`` feed per tooth, ``ap_mm`` axial depth, ``ae_mm`` radial width (or
``slot``), ``mode`` ``slot``/``up``/``down`` (optional column; default
``slot`` where ``ae_mm`` is ``slot``, else ``down``), ``diameter_mm``,
``teeth``, ``rpm`` (optional, recorded), and the mean force **on the tool**
in the tool frame: ``x`` along the feed, ``z`` up the tool axis, ``y = z x x``
(:mod:`errpred.fit`). Each bad cell is refused naming the file, line and column.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Sequence

from nc.atomic import atomic_write
from nc.errors import InputError

from .constants import FIT_MAX_TESTS
from .fit import FitResult, MeanForceTest

__all__ = ["COLUMNS", "FitFileError", "cutting_table", "read_tests", "write_cutting_table"]

#: Required columns, then optional ones.
COLUMNS = ("fz_mm", "ap_mm", "ae_mm", "diameter_mm", "teeth", "Fx_N", "Fy_N", "Fz_N")
OPTIONAL = ("mode", "rpm")


class FitFileError(InputError):
    """A tests file that cannot be used (names file, line and column)."""


def _number(path: str, line: int, col: str, text: str, positive: bool = False) -> float:
    try:
        v = float(text)
    except ValueError:
        raise FitFileError(f"{path}:{line}: {col}: expected a number, got {text!r}") from None
    if not math.isfinite(v) or (positive and v <= 0):
        raise FitFileError(f"{path}:{line}: {col}: expected a finite number"
                           f"{' > 0' if positive else ''}, got {text!r}")
    return v


def read_tests(path: str | os.PathLike) -> list[MeanForceTest]:
    """The tests of a CSV file (module docstring), checked cell by cell.

    Raises
    ------
    FitFileError
        Missing file or column, unknown column, a bad cell, no test, too many.
    """
    p = os.fspath(path)
    try:
        fh = open(p, newline="", encoding="utf-8")
    except OSError as exc:
        raise FitFileError(f"{p}: cannot read: {exc.strerror}") from None
    with fh:
        rows = [(i + 1, r) for i, r in enumerate(csv.reader(fh))
                if r and not r[0].lstrip().startswith("#") and any(c.strip() for c in r)]
    if not rows:
        raise FitFileError(f"{p}: empty; expected a header row ({','.join(COLUMNS)}) and tests")
    line0, header = rows[0]
    header = [h.strip() for h in header]
    for h in header:
        if h not in COLUMNS + OPTIONAL:
            raise FitFileError(f"{p}:{line0}: unknown column {h!r}; expected "
                               f"{', '.join(COLUMNS + OPTIONAL)}")
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise FitFileError(f"{p}:{line0}: missing column(s) {', '.join(missing)}")
    if len(rows) == 1:
        raise FitFileError(f"{p}: no test below the header")
    if len(rows) - 1 > FIT_MAX_TESTS:
        raise FitFileError(f"{p}: {len(rows) - 1} rows, more than FIT_MAX_TESTS="
                           f"{FIT_MAX_TESTS}; expected one row of mean forces per test")
    tests = []
    for line, row in rows[1:]:
        if len(row) != len(header):
            raise FitFileError(f"{p}:{line}: {len(row)} cells, expected {len(header)}")
        d = {h: c.strip() for h, c in zip(header, row)}
        slot = d["ae_mm"].lower() == "slot"
        mode = d.get("mode", "").lower() or ("slot" if slot else "down")
        if slot and mode != "slot":
            raise FitFileError(f"{p}:{line}: mode: {mode!r} with ae_mm 'slot'; expected slot")
        dia = _number(p, line, "diameter_mm", d["diameter_mm"], positive=True)
        ae = dia if slot else _number(p, line, "ae_mm", d["ae_mm"], positive=True)
        teeth_f = _number(p, line, "teeth", d["teeth"], positive=True)
        if teeth_f != int(teeth_f):
            raise FitFileError(f"{p}:{line}: teeth: expected a whole number, got {d['teeth']!r}")
        try:
            tests.append(MeanForceTest(
                fz_mm=_number(p, line, "fz_mm", d["fz_mm"], positive=True),
                ap_mm=_number(p, line, "ap_mm", d["ap_mm"], positive=True),
                ae_mm=ae, mode=mode, diameter_mm=dia, teeth=int(teeth_f),
                force_N=tuple(_number(p, line, c, d[c]) for c in ("Fx_N", "Fy_N", "Fz_N")),
                rpm=_number(p, line, "rpm", d["rpm"], positive=True) if d.get("rpm") else
                math.nan, label=f"{p}:{line}"))
        except ValueError as exc:
            if isinstance(exc, FitFileError):
                raise
            raise FitFileError(str(exc)) from None
    return tests


def cutting_table(result: FitResult, tests: Sequence[MeanForceTest], tests_file: str) -> str:
    """The ``[cutting]`` TOML table of a fit (the law, its coefficients, a source line)."""
    c = result.coefficients
    feeds = sorted({t.fz_mm for t in tests})
    src = (f"fit of {len(tests)} mean-force tests in {os.path.basename(tests_file)} "
           f"(feeds {feeds[0]:g}..{feeds[-1]:g} mm) by python -m errpred fit: RMS residual "
           f"{result.rms_N:.3g} N")
    lines = ["[cutting]", f'law = "{c.law}"']
    for k, v in c.as_dict().items():
        lines.append(f"{k} = {float(v)!r}")
    lines.append(f"source = {json.dumps(src)}")
    return "\n".join(lines) + "\n"


def write_cutting_table(path: str | os.PathLike, text: str) -> None:
    """Write the table atomically (:func:`nc.atomic.atomic_write`)."""
    with atomic_write(path) as fh:
        fh.write(text)
