"""The project's layering, checked on its real import graph (grimp: every import statement,
including those inside functions and under ``TYPE_CHECKING``).

    langenv  <-  policies  <-  train, eval  <-  bench  <-  langctrl

The env package ``langenv`` stands alone (it finds policies by name through entry points, never
by import); ``policies`` needs only ``langenv``; ``train`` and ``eval`` need ``policies`` and
``langenv`` but not each other; ``bench`` may use them all; ``langctrl`` (the command) runs any
job, by its module's name, and nothing imports it. No module imports itself back through any
chain of imports. Print the graph's summary with::

    PYTHONPATH=. python -m tests.test_architecture
"""

from __future__ import annotations

import itertools
from collections import Counter
from functools import cache
from pathlib import Path

import grimp
import pytest

PACKAGES = ("langenv", "policies", "train", "eval", "bench", "langctrl")

#: package -> the project's packages it must not import, even indirectly
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "langenv": ("policies", "train", "eval", "bench", "langctrl"),
    "policies": ("train", "eval", "bench", "langctrl"),
    "train": ("eval", "bench", "langctrl"),
    "eval": ("train", "bench", "langctrl"),
    "bench": ("langctrl",),
}


@cache
def _graph() -> grimp.ImportGraph:
    return grimp.build_graph(*PACKAGES, cache_dir=None)


def import_cycles(graph: grimp.ImportGraph) -> list[list[str]]:
    """The graph's strongly connected components of more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = itertools.count()

    def visit(v: str) -> None:
        index[v] = low[v] = next(counter)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.find_modules_directly_imported_by(v)):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for module in sorted(graph.modules):
        if module not in index:
            visit(module)
    return sorted(found)


def package_imports(graph: grimp.ImportGraph) -> Counter[tuple[str, str]]:
    """Number of direct imports from each top-level package to each other one."""
    edges: Counter[tuple[str, str]] = Counter()
    for module in graph.modules:
        for target in graph.find_modules_directly_imported_by(module):
            a, b = module.split(".")[0], target.split(".")[0]
            if a != b:
                edges[(a, b)] += 1
    return edges


@pytest.mark.parametrize(("package", "forbidden"), sorted(FORBIDDEN.items()))
def test_packages_are_layered(package: str, forbidden: tuple[str, ...]) -> None:
    graph = _graph()
    for other in forbidden:
        chain = graph.find_shortest_chain(importer=package, imported=other, as_packages=True)
        assert chain is None, f"{package} must not import {other}: {' -> '.join(chain or ())}"


def test_no_import_cycles() -> None:
    cycles = import_cycles(_graph())
    assert cycles == [], f"import cycles: {cycles}"


def test_cycle_finder_finds_a_cycle() -> None:
    graph = grimp.ImportGraph()
    for a, b in (("p.a", "p.b"), ("p.b", "p.c"), ("p.c", "p.a"), ("p.c", "p.d")):
        graph.add_import(importer=a, imported=b)
    assert import_cycles(graph) == [["p.a", "p.b", "p.c"]]


if __name__ == "__main__":
    g = _graph()
    print(f"{len(g.modules)} modules in {', '.join(PACKAGES)}")
    for (a, b), n in sorted(package_imports(g).items()):
        print(f"  {a:9s} -> {b:9s} {n:3d} imports")
    for package, forbidden in FORBIDDEN.items():
        for other in forbidden:
            chain = g.find_shortest_chain(importer=package, imported=other, as_packages=True)
            print(f"  {package} -> {other}: {'none' if chain is None else ' -> '.join(chain)}")
    print(f"import cycles: {import_cycles(g) or 'none'}")


def test_version_has_one_source() -> None:
    """``langenv.__version__`` is the installed distribution's, i.e. pyproject.toml's."""
    import tomllib

    import langenv

    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    assert langenv.__version__ == pyproject["project"]["version"]
