"""The packages' import graph: no private name imported across packages, and no
import loop inside nc, errpred or orient (read from the source with ``ast``, every
import counted, those inside functions too)."""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGES = ("nc", "errpred", "orient", "sim")


def _graph():
    mods = {}
    for pkg in PACKAGES:
        for f in (ROOT / pkg).rglob("*.py"):
            parts = f.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            mods[name] = f
    edges = {m: set() for m in mods}
    private = []
    for m, f in mods.items():
        here = m.split(".") if f.name == "__init__.py" else m.split(".")[:-1]
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[:len(here) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                top = target.split(".")[0]
                for alias in node.names:
                    full = f"{target}.{alias.name}"
                    t = full if full in mods else target
                    if t in mods and t != m:
                        edges[m].add(t)
                    if top in PACKAGES and top != m.split(".")[0] and (
                            alias.name.startswith("_")
                            or any(p.startswith("_") for p in target.split(".")[1:])):
                        private.append(f"{m} imports {full}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in mods and alias.name != m:
                        edges[m].add(alias.name)
    return mods, edges, private


def _loops(edges, package):
    """Strongly connected components of more than one module inside ``package``
    (a package's ``__init__`` re-exporting its modules is not a loop)."""
    nodes = [m for m in edges if m.split(".")[0] == package and m != package]
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in nodes:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in nodes:
        if v not in index:
            visit(v)
    return out


def test_no_private_name_crosses_a_package():
    _, _, private = _graph()
    assert private == []


@pytest.mark.parametrize("package", ["nc", "errpred", "orient"])
def test_no_import_loop_inside_the_package(package):
    mods, edges, _ = _graph()
    assert len([m for m in mods if m.startswith(package)]) > 5
    assert _loops(edges, package) == []


def test_the_loop_finder_finds_a_loop():
    edges = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "p.d": {"p.a"}}
    assert _loops(edges, "p") == [["p.a", "p.b", "p.c"]]
