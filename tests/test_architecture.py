"""The project's layering, checked on its real import graph (grimp: every import statement,
including those inside functions and under ``TYPE_CHECKING``).

    langenv  <-  policies  <-  train, eval  <-  bench  <-  langctrl

Inside ``langenv`` its *parts* (its subpackages, its top-level modules and the package root
``langenv/__init__``, every module counted, ``__main__`` too) follow one declared order,
:data:`LANGENV_LAYERS`, lowest first: a part imports only parts of the layers below its own, so no
two import each other, directly or through others (:func:`langenv_part_cycles`). The jobs that
run the parts from the command line live above them all, in ``langctrl.jobs``. Every module that
compiles kernels or declares a layout is watched by the kernels' stale-cache check
(``langenv.kernels.SOURCES``).

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

from langenv.speech.graph_checks import strongly_connected

PACKAGES = ("langenv", "policies", "train", "eval", "bench", "langctrl")

#: langenv's parts in layers, lowest first: a part may import only parts of the layers below its
#: own. ``__init__`` is the package root (the version, the env's registration, and MuJoCo's GL
#: backend chosen through ``robot.gl`` before anything loads MuJoCo). docs/ARCHITECTURE.md shows it.
LANGENV_LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "files", "vec"),
    ("layout", "validation"),
    ("kernels",),
    ("robot", "task"),
    ("__init__",),
    ("control",),
    ("speech",),
    ("exercise", "users"),
    ("motion", "worlds"),
    ("env_kernels",),
    ("compiled_steps",),
    ("env",),
    ("batch", "live", "script_fit"),
)

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
    imports = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in sorted(graph.modules)}
    return sorted(sorted(c) for c in strongly_connected(imports) if len(c) > 1)


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


def part_of(module: str) -> str | None:
    """The part of ``langenv`` that ``module`` belongs to (``__init__`` for the package root), or
    None outside ``langenv``. Every module counts, ``__main__`` modules too."""
    names = module.split(".")
    if names[0] != "langenv":
        return None
    return names[1] if len(names) > 1 else "__init__"


def part_graph(graph: grimp.ImportGraph) -> grimp.ImportGraph:
    """``langenv``'s parts and which imports which (directly, by any of their modules)."""
    parts = grimp.ImportGraph()
    for module in {"langenv"} | graph.find_descendants("langenv"):
        a = part_of(module)
        if a is None:
            continue
        parts.add_module(a)
        for target in graph.find_modules_directly_imported_by(module):
            b = part_of(target)
            if b is not None and b != a:
                parts.add_import(importer=a, imported=b)
    return parts


def langenv_part_cycles(graph: grimp.ImportGraph) -> list[list[str]]:
    """Groups of ``langenv``'s parts that import each other (directly or through others)."""
    return import_cycles(part_graph(graph))


def layers(parts: grimp.ImportGraph) -> list[list[str]]:
    """The parts in layers: each imports only parts of the layers before it (the graph has no
    cycle)."""
    placed: dict[str, int] = {}

    def depth(p: str) -> int:
        if p not in placed:
            below = parts.find_modules_directly_imported_by(p)
            placed[p] = 1 + max((depth(q) for q in below), default=-1)
        return placed[p]

    for p in parts.modules:
        depth(p)
    out: list[list[str]] = [[] for _ in range(max(placed.values(), default=-1) + 1)]
    for p, d in placed.items():
        out[d].append(p)
    return [sorted(layer) for layer in out]


def test_langenv_parts_import_no_cycle() -> None:
    cycles = langenv_part_cycles(_graph())
    chains = []
    graph = _graph()
    for group in cycles:
        for a, b in itertools.permutations(group, 2):
            chain = graph.find_shortest_chain(
                importer=_module(a), imported=_module(b), as_packages="__init__" not in (a, b)
            )
            chains.append(" -> ".join(chain or ()))
    assert cycles == [], f"langenv's parts import each other: {cycles}; e.g. {chains[:4]}"


def test_langenv_parts_follow_the_declared_layers() -> None:
    """Every part is declared once, and imports only parts of the layers below its own."""
    graph = _graph()
    parts = part_graph(graph)
    declared = [p for layer in LANGENV_LAYERS for p in layer]
    assert len(declared) == len(set(declared)), "a part declared twice"
    assert sorted(parts.modules) == sorted(declared), "the declared parts are langenv's parts"
    level = {p: i for i, layer in enumerate(LANGENV_LAYERS) for p in layer}
    upward = []
    for a in sorted(parts.modules):
        for b in sorted(parts.find_modules_directly_imported_by(a)):
            if level[b] >= level[a]:
                chain = graph.find_shortest_chain(
                    importer=_module(a), imported=_module(b), as_packages="__init__" not in (a, b)
                )
                upward.append(f"{a} -> {b}: {' -> '.join(chain or ())}")
    assert upward == [], f"imports not downward in LANGENV_LAYERS: {upward}"


def _module(part: str) -> str:
    return "langenv" if part == "__init__" else f"langenv.{part}"


def test_the_kernels_stale_cache_check_watches_every_compiled_module() -> None:
    """Every module that compiles kernels (``@kernel``, ``@inline``, ``@jit``) or declares
    state (``Field(``) is in ``langenv.kernels.SOURCES``, and those that compile in ``COMPILED``
    (the vocoder's kernels, self-contained, apart)."""
    from langenv.kernels import COMPILED, SOURCES

    root = Path(__file__).resolve().parents[1] / "langenv"
    compiling, declaring = set(), set()
    for path in root.rglob("*.py"):
        name = path.relative_to(root).as_posix()
        text = path.read_text()
        if any(f"\n@{d}\n" in text for d in ("kernel", "inline", "jit")):
            compiling.add(name)
        if "Field(" in text:
            declaring.add(name)
    compiling.discard("speech/vocoder_kernels.py")
    assert sorted(compiling - set(COMPILED)) == []
    assert sorted(declaring - set(SOURCES)) == []
    assert set(COMPILED) <= set(SOURCES)
    for name in SOURCES:
        assert (root / name).is_file(), name


REPO = Path(__file__).resolve().parents[1]


def _sources(*skip: str) -> list[Path]:
    """The project's Python files outside ``tests/``, ``tools/`` and ``skip`` (paths)."""
    found = []
    for package in PACKAGES:
        for path in sorted((REPO / package).rglob("*.py")):
            if path.relative_to(REPO).as_posix() not in skip:
                found.append(path)
    return found


def test_only_langctrl_builds_a_command_line() -> None:
    """Every command-line job lives in ``langctrl.jobs``: no module of ``langenv``, ``policies``,
    ``train``, ``eval`` or ``bench`` makes an argparse parser (``tools/`` and ``tests/`` may)."""
    found = [
        f"{path.relative_to(REPO)}:{i}"
        for path in _sources()
        if path.parts[len(REPO.parts)] != "langctrl"
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
        if "ArgumentParser(" in line
    ]
    assert found == []


def test_the_shared_options_are_added_in_one_place() -> None:
    """The options the jobs share (:data:`langctrl.options.COMMON_OPTIONS`) are added only by
    ``langctrl/options.py``; a job takes them as parents."""
    import re

    from langctrl.options import COMMON_OPTIONS

    added = re.compile(
        r"add_argument\(\s*[\"'](" + "|".join(re.escape(o) for o in COMMON_OPTIONS) + r")[\"']"
    )
    found = [
        f"{path.relative_to(REPO)}: {m.group(1)}"
        for path in _sources("langctrl/options.py")
        for m in added.finditer(path.read_text(encoding="utf-8"))
    ]
    assert found == []


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
    cycles = langenv_part_cycles(g)
    pairs = sum(len(group) * (len(group) - 1) // 2 for group in cycles)
    print(f"cycles among langenv's parts: {cycles or 'none'} ({pairs} pairs)")
    top = sorted(p.name for p in (Path(__file__).resolve().parents[1] / "langenv").glob("*.py"))
    print(f"modules at langenv's top: {len(top)} ({', '.join(top)})")
    for i, layer in enumerate(LANGENV_LAYERS):
        print(f"  declared layer {i}: {', '.join(layer)}")
    for i, layer in enumerate(layers(part_graph(g))):
        print(f"  langenv layer {i}: {', '.join(layer)}")


def test_version_has_one_source() -> None:
    """``langenv.__version__`` is the installed distribution's, i.e. pyproject.toml's."""
    import tomllib

    import langenv

    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    assert langenv.__version__ == pyproject["project"]["version"]
