"""Error-level findings of a prediction: what makes a program unfit to run as it is.

Two kinds, each found in stage 1 (:mod:`errpred.geometry`):

* ``rapid-into-material``: a rapid move (G0) through material
  (:data:`errpred.geometry.ERROR_STATUSES`), found by the whole-block pre-check
  (:meth:`errpred.geometry.GeometryModel.geometry`): a crash.
* ``above-flutes``: a cut deeper than the flutes are long
  (:attr:`errpred.geometry.PointGeometry.above_flutes`): the shank meets the
  material (the holder is not tested). The tool's ``flute_length_mm`` decides (2 D where the scenario
  does not give it), and the finding names it.

``predict`` reports them and ends with exit status 1; ``compensate`` and the main job
refuse the program before correcting it.
"""

from __future__ import annotations

import math

from .geometry import ERROR_STATUSES, STATUS
from .predict import Prediction

__all__ = ["FINDINGS", "error_findings", "findings_line"]

#: The kinds of error finding, and what each means.
FINDINGS = {
    **{s: STATUS[s] for s in ERROR_STATUSES},
    "above-flutes": ("the cut reaches above the flutes: the shank meets material; the "
                     "program must not be run with this tool"),
}


def error_findings(prediction: Prediction) -> list[dict]:
    """One record per point with an error: ``line``, ``block``, ``status`` (a key of
    :data:`FINDINGS`), ``reason``, ``point_mm`` (where the tool meets the material),
    and for ``above-flutes`` the ``flute_length_mm`` it was judged with."""
    out = []
    flutes = prediction.flute_length_mm
    for p in prediction.points:
        kind = (p.status if p.status in ERROR_STATUSES
                else "above-flutes" if p.geometry.above_flutes else None)
        if kind is None:
            continue
        rec = {"line": p.line, "block": p.block, "status": kind, "reason": FINDINGS[kind],
               "point_mm": [round(float(x), 4) for x in p.geometry.tip]}
        if kind == "above-flutes":
            rec["flute_length_mm"] = flutes if math.isfinite(flutes) else None
        out.append(rec)
    return out


def findings_line(findings: list[dict], file: str | None = None) -> str:
    """The findings in one line (empty string for none)."""
    if not findings:
        return ""
    parts = []
    rapid = [f for f in findings if f["status"] in ERROR_STATUSES]
    deep = [f for f in findings if f["status"] == "above-flutes"]
    if rapid:
        n = len(rapid)
        parts.append(f"{n} rapid move{'s' if n > 1 else ''} (G0) into material at "
                     f"{_lines(rapid)}: a crash")
    if deep:
        n = len({f["line"] for f in deep})
        flutes = deep[0].get("flute_length_mm")
        long = f"{flutes:g} mm" if flutes is not None and math.isfinite(flutes) else "?"
        parts.append(f"{n} cut{'s' if n > 1 else ''} deeper than the flutes "
                     f"({long}, [tool] flute_length_mm) at "
                     f"{_lines(deep)}: the shank meets material")
    where = f"{file}: " if file else ""
    return f"{where}{'; '.join(parts)}; the program must not be run as it is"


def _lines(findings: list[dict]) -> str:
    """``line 6`` or ``lines 6, 9, 12 and 4 more`` (each source line once)."""
    lines = list(dict.fromkeys(f["line"] for f in findings))
    more = f" and {len(lines) - 5} more" if len(lines) > 5 else ""
    return f"line{'s' if len(lines) > 1 else ''} {', '.join(map(str, lines[:5]))}{more}"
