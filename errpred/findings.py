"""Error-level findings of a prediction: what makes a program unfit to run as it is.

Today one kind: a rapid move (G0) through material (:data:`errpred.geometry.ERROR_STATUSES`),
found by the whole-block pre-check (:meth:`errpred.geometry.GeometryModel.geometry`).
``predict`` reports them and ends with exit status 1; ``compensate`` and the main job
refuse the program before correcting it.
"""

from __future__ import annotations

from .geometry import ERROR_STATUSES, STATUS
from .predict import Prediction

__all__ = ["error_findings", "findings_line"]


def error_findings(prediction: Prediction) -> list[dict]:
    """One record per point with an error status: ``line``, ``block``, ``status``,
    ``reason``, ``point_mm`` (where the tool meets the material)."""
    out = []
    for p in prediction.points:
        if p.status in ERROR_STATUSES:
            out.append({"line": p.line, "block": p.block, "status": p.status,
                        "reason": STATUS[p.status],
                        "point_mm": [round(float(x), 4) for x in p.geometry.tip]})
    return out


def findings_line(findings: list[dict], file: str | None = None) -> str:
    """The findings in one line (empty string for none)."""
    if not findings:
        return ""
    lines = ", ".join(str(f["line"]) for f in findings[:5])
    more = f" and {len(findings) - 5} more" if len(findings) > 5 else ""
    where = f"{file}: " if file else ""
    n = len(findings)
    return (f"{where}{n} rapid move{'s' if n > 1 else ''} (G0) into material at line"
            f"{'s' if n > 1 else ''} {lines}{more}: a crash; the program must not be run "
            "as it is")
