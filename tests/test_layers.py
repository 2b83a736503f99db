"""The import layers of flexkin (issue 29): no import runs up a layer, and no import cycle.

:data:`LAYERS` is the one declaration of the layer order (top first; DESIGN.md shows the same
list), in the spirit of python-control's docstring test, which declares its parameter rules in
one table.  The graph is read from the source with :mod:`ast`: every ``import`` and ``from ...
import`` of a flexkin module, at module level, inside functions (imported on first use) and
under ``if TYPE_CHECKING:`` alike.  A lazy import is still a dependency, so it obeys the same
rules; :data:`ALLOWED` would list an exception with its reason (it is empty).

A module may import modules of its own layer or of lower layers.  No module imports the package
``flexkin`` itself (its ``__init__`` is the public facade, above every layer): each imports what
it uses from the module that defines it.  The last tests feed the checks made-up graphs, to show
that they fail on an upward import and on a cycle.
"""

from __future__ import annotations

import ast
import importlib
import pkgutil
from pathlib import Path

import pytest

import flexkin

#: the layer order, top first; the names in one entry share a layer (DESIGN.md, "Layer order").
#: Every top-level module or subpackage of flexkin must be listed.
LAYERS: list[tuple[str, ...]] = [
    ("cli",),
    ("explore", "study", "reproduce", "calibration"),
    ("solve",),
    ("results",),
    ("analysis",),
    ("plot",),
    ("system",),
    ("cosserat",),
    ("rod",),
    ("mechanism",),
    ("io",),
    ("core", "errors", "_moved"),
]

#: (importer, imported) -> reason: an upward or cyclic import accepted on purpose (none)
ALLOWED: dict[tuple[str, str], str] = {}

ROOT = "flexkin"
SRC = Path(flexkin.__file__).resolve().parent
RANK = {name: k for k, group in enumerate(LAYERS) for name in group}


def module_files(src: Path = SRC, root: str = ROOT) -> dict[str, tuple[Path, bool]]:
    """Every module of the package: dotted name -> (file, is a package ``__init__``)."""
    out = {}
    for p in sorted(src.rglob("*.py")):
        parts = [root, *p.relative_to(src).with_suffix("").parts]
        ispkg = parts[-1] == "__init__"
        if ispkg:
            parts = parts[:-1]
        out[".".join(parts)] = (p, ispkg)
    return out


def _imported(node: ast.AST, module: str, ispkg: bool, known: set[str]) -> list[str]:
    """The flexkin modules an import statement loads (``from X import y``: ``X.y`` if that is a
    module, else ``X``)."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    elif isinstance(node, ast.ImportFrom):
        if node.level:
            base = module.split(".") if ispkg else module.split(".")[:-1]
            base = base[:len(base) - (node.level - 1)]
            frm = ".".join(base + ([node.module] if node.module else []))
        else:
            frm = node.module or ""
        names = [f"{frm}.{a.name}" if f"{frm}.{a.name}" in known else frm for a in node.names]
    else:
        return []
    out = []
    for name in names:
        if name != ROOT and not name.startswith(ROOT + "."):
            continue
        while name not in known and "." in name:   # e.g. "flexkin.rod.kernels.eval_rod"
            name = name.rsplit(".", 1)[0]
        out.append(name)
    return out


def import_graph(src: Path = SRC, root: str = ROOT) -> dict[str, set[str]]:
    """module -> the flexkin modules it imports (anywhere in its source)."""
    files = module_files(src, root)
    known = set(files)
    graph: dict[str, set[str]] = {}
    for mod, (path, ispkg) in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        graph[mod] = {t for node in ast.walk(tree) for t in _imported(node, mod, ispkg, known) if t != mod}
    return graph


def layer_of(module: str) -> str | None:
    """The layer name of a module (its top-level name below the package), ``None`` for the package."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def upward_imports(graph: dict[str, set[str]], rank: dict[str, int] = RANK) -> list[tuple[str, str]]:
    """Imports of a higher layer (smaller rank) or of the package facade itself."""
    bad = []
    for a, targets in graph.items():
        la = layer_of(a)
        if la is None:          # the package facade may import every layer (lazily)
            continue
        for b in targets:
            lb = layer_of(b)
            if (lb is None or rank[lb] < rank[la]) and (a, b) not in ALLOWED:
                bad.append((a, b))
    return sorted(bad)


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan, iterative), i.e.
    the import cycles; edges to the package facade and those in :data:`ALLOWED` are left out."""
    edges = {a: sorted(b for b in bs if layer_of(b) is not None and (a, b) not in ALLOWED)
             for a, bs in graph.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, 0)]
        while work:
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = len(index)
                stack.append(v)
                on_stack.add(v)
            succ = edges.get(v, [])
            for k in range(i, len(succ)):
                w = succ[k]
                if w not in index:
                    work.append((v, k + 1))
                    work.append((w, 0))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
                if work:
                    u = work[-1][0]
                    low[u] = min(low[u], low[v])
    return out


# ---------------------------------------------------------------------------------------------
GRAPH = import_graph()


def test_every_module_imports():
    """Every module imports (a cycle at module level would fail here with a partly initialised
    module).  The modules are listed from the files, not by ``pkgutil.walk_packages``, which
    does not enter a namespace package (``analysis`` has no ``__init__``);
    ``__main__`` modules run a program, so they are only parsed."""
    names = sorted(m for m in GRAPH if not m.endswith("__main__"))
    walked = {m.name for m in pkgutil.walk_packages(flexkin.__path__, "flexkin.")}
    assert walked <= set(GRAPH)
    for name in names:
        importlib.import_module(name)


def test_every_layer_is_declared():
    """A new top-level module or subpackage must be placed in :data:`LAYERS`."""
    top = {layer_of(m) for m in GRAPH} - {None}
    assert top - set(RANK) == set(), "add these to LAYERS"
    assert set(RANK) - top == set(), "LAYERS names modules that do not exist"


def test_the_graph_sees_the_imports():
    """The parser finds known imports: module level, relative, and lazy (inside a function)."""
    assert "flexkin.system" in GRAPH["flexkin.solve.ik"]                       # from ..system import System
    assert "flexkin.analysis.feasibility" in GRAPH["flexkin.solve.workspace"]  # inside _CellChecks._collide
    assert "flexkin.plot.rod" in GRAPH["flexkin.solve.rod_inverse"]            # inside RodInverseResult.plot


def test_no_import_runs_up_a_layer():
    bad = upward_imports(GRAPH)
    assert bad == [], "imports from a higher layer:\n" + "\n".join(f"  {a} -> {b}" for a, b in bad)


def test_no_import_cycles():
    found = cycles(GRAPH)
    assert found == [], "import cycles:\n" + "\n".join("  " + " <-> ".join(c) for c in found)


# ---- the checks can fail ---------------------------------------------------------------------
def test_an_upward_import_is_found():
    graph = {k: set(v) for k, v in GRAPH.items()}
    graph["flexkin.rod.state"].add("flexkin.plot.rod")     # rod below plot
    graph["flexkin.core.geometry2d"].add("flexkin")        # the facade
    assert upward_imports(graph) == [("flexkin.core.geometry2d", "flexkin"), ("flexkin.rod.state", "flexkin.plot.rod")]


@pytest.mark.parametrize("extra", [
    [("flexkin.solve.leg_curve", "flexkin.solve.curves")],   # a 2-cycle through curves -> leg_curve
    [("flexkin.core.jit", "flexkin.core.budget"), ("flexkin.core.budget", "flexkin.core.jit")],
])
def test_a_cycle_is_found(extra):
    graph = {k: set(v) for k, v in GRAPH.items()}
    for a, b in extra:
        graph[a].add(b)
    found = cycles(graph)
    assert len(found) == 1 and {a for a, _ in extra} <= set(found[0])


def test_relative_imports_resolve(tmp_path):
    """A made-up package: relative imports from a module and from a package ``__init__``,
    ``from . import module`` and a name imported from a module."""
    pkg = tmp_path / "flexkin"
    (pkg / "low").mkdir(parents=True)
    (pkg / "high").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "low" / "__init__.py").write_text("from .a import f\n")
    (pkg / "low" / "a.py").write_text("def f():\n    from ..high import b\n")
    (pkg / "high" / "__init__.py").write_text("from . import b\n")
    (pkg / "high" / "b.py").write_text("from ..low.a import f\nimport flexkin\n")
    g = import_graph(pkg)
    assert g["flexkin.low"] == {"flexkin.low.a"}
    assert g["flexkin.low.a"] == {"flexkin.high.b"}
    assert g["flexkin.high"] == {"flexkin.high.b"}
    assert g["flexkin.high.b"] == {"flexkin.low.a", "flexkin"}
    assert upward_imports(g, {"high": 0, "low": 1}) == [("flexkin.high.b", "flexkin"), ("flexkin.low.a", "flexkin.high.b")]
    assert cycles(g) == [["flexkin.high.b", "flexkin.low.a"]]
