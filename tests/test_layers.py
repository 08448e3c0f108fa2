"""The packages' import graph: dependencies point one way, nc <- errpred <- orient <-
sim (no module imports a package above its own); no private name imported across
packages; no import loop inside any package (read from the source with ``ast``, every
import counted, those inside functions and under ``TYPE_CHECKING`` too)."""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
#: The packages, lowest first: each may import those before it, none after it.
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


def _upward(edges) -> list[str]:
    """Imports of a module from a package above its own (``PACKAGES`` order)."""
    rank = {p: k for k, p in enumerate(PACKAGES)}
    return sorted(f"{m} imports {t}" for m, ts in edges.items() for t in ts
                  if rank[t.split(".")[0]] > rank[m.split(".")[0]])


def test_no_package_imports_a_package_above_it():
    mods, edges, _ = _graph()
    assert {m.split(".")[0] for m in mods} == set(PACKAGES)
    assert _upward(edges) == []


def test_the_layer_check_finds_an_import_inside_a_function(tmp_path, monkeypatch):
    """An upward import hidden in a function (as orient.cli's hand-over to sim.job_cli
    was) is found, and so is a loop made of imports inside functions."""
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "sim" / "job.py").write_text("X = 1\n")
    (tmp_path / "orient" / "cli.py").write_text(
        "def run():\n    from sim.job import X\n    return X\n")
    (tmp_path / "orient" / "a.py").write_text("def f():\n    from . import b\n")
    (tmp_path / "orient" / "b.py").write_text("def g():\n    from .a import f\n")
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    _, edges, _ = _graph()
    assert _upward(edges) == ["orient.cli imports sim.job"]
    assert _loops(edges, "orient") == [["orient.a", "orient.b"]]


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_loop_inside_the_package(package):
    mods, edges, _ = _graph()
    assert len([m for m in mods if m.startswith(package)]) > 5
    assert _loops(edges, package) == []


def test_the_loop_finder_finds_a_loop():
    edges = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "p.d": {"p.a"}}
    assert _loops(edges, "p") == [["p.a", "p.b", "p.c"]]
