"""A single self-contained HTML page: headings, text, tables and PNG figures embedded.

No scripts, no external resources: the page opens anywhere, offline, and a
person reads the result from it alone. The figures are the PNG bytes that the
plotting modules write, embedded as ``data:`` URIs. No physics: the pages of
``errpred predict`` and ``compensate`` (:mod:`errpred.run_page`), of the simulated
machine's run (``sim.cli``) and of the main job (``sim.job_report``) are all made here.
"""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass, field
from pathlib import Path

from nc.atomic import atomic_write

__all__ = ["Figure", "Section", "render_page", "write_page"]

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 1000px; margin: 2em auto;
       padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.8em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
th { background: #f2f2f2; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #555; }
.verdict { font-size: 1.1em; padding: 0.5em 0.8em; background: #eef6ee;
           border-left: 4px solid #3a3; }
.verdict.bad { background: #fbeeee; border-left-color: #c33; }
"""


@dataclass(frozen=True)
class Figure:
    """A PNG figure: its bytes and a caption."""

    png: bytes
    caption: str


@dataclass(frozen=True)
class Section:
    """A heading with paragraphs, tables (header row first) and figures."""

    heading: str
    paragraphs: tuple[str, ...] = ()
    tables: tuple[tuple[tuple[str, ...], ...], ...] = ()
    figures: tuple[Figure, ...] = field(default_factory=tuple)


def _table(rows: tuple[tuple[str, ...], ...]) -> str:
    if not rows:
        return ""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in rows[0])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                   for r in rows[1:])
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _figure(f: Figure) -> str:
    if f.png[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"figure {f.caption!r}: expected PNG bytes")
    data = base64.b64encode(f.png).decode("ascii")
    cap = html.escape(f.caption)
    return (f'<figure><img alt="{cap}" src="data:image/png;base64,{data}">'
            f"<figcaption>{cap}</figcaption></figure>")


def render_page(title: str, verdict: str, sections: list[Section], *, good: bool = True) -> str:
    """The page as a string.

    Parameters
    ----------
    title : str
        The page's title and top heading.
    verdict : str
        One sentence at the top: the result.
    sections : list of Section
    good : bool
        Colour of the verdict box (green/red).
    """
    parts = [f"<h1>{html.escape(title)}</h1>",
             f'<p class="verdict{"" if good else " bad"}">{html.escape(verdict)}</p>']
    for s in sections:
        parts.append(f"<h2>{html.escape(s.heading)}</h2>")
        parts.extend(f"<p>{html.escape(p)}</p>" for p in s.paragraphs)
        parts.extend(_table(t) for t in s.tables)
        parts.extend(_figure(f) for f in s.figures)
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_CSS}</style></head>"
            f"<body>{''.join(parts)}</body></html>\n")


def write_page(path: str | Path, title: str, verdict: str, sections: list[Section], *,
               good: bool = True) -> None:
    """:func:`render_page` written atomically to ``path`` (:func:`nc.atomic.atomic_write`)."""
    text = render_page(title, verdict, sections, good=good)
    with atomic_write(path) as fh:
        fh.write(text)
