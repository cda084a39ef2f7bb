"""Rules a machine checks (issue 11, §4): the static type check is clean, imports go one way through
the pipeline's layers, no import cycle, modules stay small.

The import rules read every module under ``src/sicomat`` with :mod:`ast`: every ``import`` and ``from
... import`` of a sicomat module counts, at module level, inside functions (lazy imports) and under
``if TYPE_CHECKING:`` (an annotation that names a higher layer's type is a dependency on it too).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = SRC / "sicomat"

# --------------------------------------------------------------------------- the layers
# Which layer a module belongs to: the first name below ``sicomat`` (``sicomat.servo.loop`` → servo).
FOUNDATION = {"errors", "budget", "progress"}

# What each layer may import, written out (docs/architecture.md has the same table). Read it as the
# pipeline: foundation ← description ← io;  lti ← mechanics ← servo ← {simulation, frequency} ←
# {tuning, reduction} ← tasks ← studies ← cli;  motion beside description (servo and above may use it);
# plots: figures of result objects, imported only lazily by a ``plot`` method (or by tasks/studies/cli).
# io (model file, atomic writes, CSV) needs only description: the stages from simulation up may use it,
# their results write themselves through it (TimeSeries.to_csv → io.csv, save_figure → io.atomic).
_CORE = {"foundation", "description", "catalogue", "lti", "mechanics", "robotics", "motion", "servo"}
_ANALYSES = _CORE | {"io"}
ALLOWED: dict[str, set[str]] = {
    "foundation": set(),
    "description": {"foundation"},
    "catalogue": {"foundation", "description"},
    "io": {"foundation", "description", "catalogue"},
    "motion": {"foundation", "description"},
    "lti": {"foundation"},
    "mechanics": {"foundation", "description", "lti"},
    # beside mechanics (issue 13): its lowering produces a Mechanics (robotics.lowering.axis_mechanics, the
    # one way from any machine axis to its mechanics, which the servo loop and the analyses above use)
    "robotics": {"foundation", "description", "lti", "mechanics"},
    "servo": {"foundation", "description", "lti", "mechanics", "motion", "robotics"},
    "simulation": _ANALYSES,
    "frequency": _ANALYSES,
    "tuning": _ANALYSES | {"simulation", "frequency"},
    "reduction": _ANALYSES | {"simulation", "frequency"},
    "plots": _ANALYSES | {"simulation", "frequency", "tuning", "reduction"},
    "tasks": _ANALYSES | {"simulation", "frequency", "tuning", "reduction", "plots"},
    # parameter studies (issue 14): above tasks, beside the CLI; only the CLI imports them
    "studies": _ANALYSES | {"simulation", "frequency", "tuning", "reduction", "plots", "tasks"},
    "cli": _ANALYSES | {"simulation", "frequency", "tuning", "reduction", "plots", "tasks", "studies"},
}
PLOT_METHOD = "plot"
"""The one allowed back-reference: a result's ``plot`` method imports ``plots/`` lazily."""
FACADE = "sicomat"
"""``sicomat/__init__`` re-exports the pipeline's verbs (lazily, PEP 562): it is above every layer
but the CLI and is left out of the rules."""

# Today's violations, each with why it is there; the test fails on any other, and on an entry that
# is gone (remove it then). Format: (importing module, imported module).
KNOWN_VIOLATIONS: dict[tuple[str, str], str] = {
}


def layer_of(module: str) -> str:
    parts = module.split(".")
    if parts == [FACADE]:
        return FACADE
    top = parts[1]
    return "foundation" if top in FOUNDATION else top


# --------------------------------------------------------------------------- reading imports
@dataclass(frozen=True)
class Import:
    source: str            # importing module, e.g. "sicomat.servo.loop"
    target: str            # imported sicomat module (a submodule when the name is one)
    line: int
    lazy: bool             # inside a function
    function: str | None   # the innermost enclosing function's name
    type_only: bool        # under ``if TYPE_CHECKING:``


def module_name(path: Path, src: Path = SRC) -> str:
    rel = path.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def all_modules(package: Path = PACKAGE) -> dict[str, Path]:
    return {module_name(p): p for p in sorted(package.rglob("*.py"))}


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports_of(source_text: str, module: str, is_package: bool, known: set[str]) -> list[Import]:
    """Every import of a sicomat module in one module's source text.

    ``known`` is the set of sicomat module names: ``from .pkg import name`` points at the submodule
    ``pkg.name`` when there is one, else at ``pkg``.
    """
    tree = ast.parse(source_text)
    package = module if is_package else module.rpartition(".")[0]
    found: list[Import] = []

    def resolve(node: ast.ImportFrom) -> str:
        if node.level == 0:
            return node.module or ""
        base = package.split(".")
        base = base[:len(base) - (node.level - 1)]
        return ".".join(base + ([node.module] if node.module else []))

    def add(target: str, node: ast.stmt, function: str | None, type_only: bool) -> None:
        if target == "sicomat" or target.startswith("sicomat."):
            found.append(Import(module, target, node.lineno, function is not None, function, type_only))

    def visit(node: ast.AST, function: str | None, type_only: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, child.name, type_only)
            elif isinstance(child, ast.If) and _is_type_checking(child.test):
                for stmt in child.body:
                    visit_stmt(stmt, function, True)
                for stmt in child.orelse:
                    visit_stmt(stmt, function, type_only)
            else:
                visit_stmt(child, function, type_only)

    def visit_stmt(child: ast.AST, function: str | None, type_only: bool) -> None:
        if isinstance(child, ast.Import):
            for alias in child.names:
                add(alias.name, child, function, type_only)
        elif isinstance(child, ast.ImportFrom):
            base = resolve(child)
            for alias in child.names:
                sub = f"{base}.{alias.name}"
                add(sub if sub in known else base, child, function, type_only)
        elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
            visit(child, child.name, type_only)
        else:
            visit(child, function, type_only)

    visit(tree, None, False)
    return found


def project_imports() -> list[Import]:
    modules = all_modules()
    known = set(modules)
    out: list[Import] = []
    for name, path in modules.items():
        out += imports_of(path.read_text(encoding="utf-8"), name, path.name == "__init__.py", known)
    return out


# --------------------------------------------------------------------------- the rules
def violation(imp: Import) -> str | None:
    """Why an import breaks the layering, or None."""
    src, dst = layer_of(imp.source), layer_of(imp.target)
    if FACADE in (src, dst):
        return None if dst != "cli" else "nothing imports cli"
    if src == dst:
        return None
    if dst == "cli":
        return "nothing imports cli"
    if dst == "plots" and src not in ("tasks", "studies", "cli"):
        if imp.lazy and imp.function == PLOT_METHOD and not imp.type_only:
            return None
        return "plots/ is imported only lazily, from inside a `plot` method (or by tasks/studies/cli)"
    if dst not in ALLOWED[src]:
        return f"{src} may import only {', '.join(sorted(ALLOWED[src])) or 'nothing'}, not {dst}"
    return None


def violations(imports: list[Import]) -> dict[tuple[str, str], str]:
    found = {}
    for imp in imports:
        why = violation(imp)
        if why is not None:
            found.setdefault((imp.source, imp.target), f"line {imp.line}: {why}")
    return found


def runtime_graph(imports: list[Import]) -> dict[str, set[str]]:
    """Module → modules it imports when it runs (``TYPE_CHECKING`` imports never run), without the
    allowed ``.plot()`` → ``plots/`` edges and without the facade."""
    graph: dict[str, set[str]] = {}
    for imp in imports:
        if imp.type_only or FACADE in (imp.source, imp.target) or imp.source == imp.target:
            continue
        if layer_of(imp.target) == "plots" and imp.function == PLOT_METHOD and layer_of(imp.source) != "plots":
            continue
        graph.setdefault(imp.source, set()).add(imp.target)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    nodes = sorted(set(graph) | {t for ts in graph.values() for t in ts})
    counter = 0
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        out.append(sorted(component))
    return sorted(out)


# Import cycles of today, each with why (the test fails on a new one and on one that is gone).
KNOWN_CYCLES: dict[tuple[str, ...], str] = {
}


# --------------------------------------------------------------------------- tests
def test_every_module_belongs_to_a_layer():
    layers = {layer_of(name) for name in all_modules()} - {FACADE}
    assert layers <= set(ALLOWED), f"modules outside the layer table: {sorted(layers - set(ALLOWED))}"


def test_imports_go_one_way_through_the_layers():
    found = violations(project_imports())
    new = {k: v for k, v in found.items() if k not in KNOWN_VIOLATIONS}
    gone = set(KNOWN_VIOLATIONS) - set(found)
    assert not new, "imports against the layering:\n" + "\n".join(
        f"  {a} → {b} ({why})" for (a, b), why in sorted(new.items()))
    assert not gone, f"fixed, remove them from KNOWN_VIOLATIONS: {sorted(gone)}"


def test_no_import_cycle_but_the_plot_methods():
    found = {tuple(c): c for c in cycles(runtime_graph(project_imports()))}
    new = [c for key, c in found.items() if key not in KNOWN_CYCLES]
    gone = set(KNOWN_CYCLES) - set(found)
    assert not new, "import cycles (modules that import each other, lazily or not):\n" + "\n".join(
        "  " + " ⇄ ".join(c) for c in new)
    assert not gone, f"fixed, remove them from KNOWN_CYCLES: {sorted(gone)}"


_KNOWN = {"sicomat.errors", "sicomat.servo", "sicomat.servo.loop", "sicomat.frequency", "sicomat.frequency.loops",
          "sicomat.plots", "sicomat.plots.base", "sicomat.cli", "sicomat.cli.main", "sicomat.lti",
          "sicomat.lti.plant", "sicomat.mechanics", "sicomat.mechanics.lumped", "sicomat.tasks",
          "sicomat.tasks.analysis", "sicomat.studies", "sicomat.studies.pareto", "sicomat.plots.study"}


@pytest.mark.parametrize("module, text, expected", [
    # a lower layer importing a higher one, lazily inside a function
    ("sicomat.servo.loop", "def f():\n    from ..frequency.loops import LoopAnalysis\n",
     {("sicomat.servo.loop", "sicomat.frequency.loops")}),
    # ... or only for an annotation
    ("sicomat.lti.plant", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..mechanics import lumped\n",
     {("sicomat.lti.plant", "sicomat.mechanics.lumped")}),
    # plots/ at module level, or lazily but not from a `plot` method
    ("sicomat.frequency.loops", "from ..plots.base import save_figure\n",
     {("sicomat.frequency.loops", "sicomat.plots.base")}),
    ("sicomat.frequency.loops", "class R:\n    def show(self):\n        from ..plots import base\n",
     {("sicomat.frequency.loops", "sicomat.plots.base")}),
    # anything importing cli, absolute import included
    ("sicomat.servo.loop", "import sicomat.cli.main\n", {("sicomat.servo.loop", "sicomat.cli.main")}),
    # allowed: downwards, the lazy `.plot()`, inside the same layer, and the CLI using plots
    ("sicomat.frequency.loops", "from ..servo.loop import ServoLoop\nfrom . import loops\n"
     "class R:\n    def plot(self):\n        from ..plots.base import save_figure\n", set()),
    ("sicomat.cli.main", "from ..plots.base import save_figure\n", set()),
    # studies (issue 14): above tasks, beside the CLI; they may use plots and tasks, only the CLI uses them
    ("sicomat.studies.pareto", "from ..plots.study import pareto_plot\nfrom ..tasks import analysis\n", set()),
    ("sicomat.cli.main", "from ..studies.pareto import pareto_front\n", set()),
    ("sicomat.studies.pareto", "from ..cli import main\n", {("sicomat.studies.pareto", "sicomat.cli.main")}),
    ("sicomat.tasks.analysis", "def f():\n    from ..studies import pareto\n",
     {("sicomat.tasks.analysis", "sicomat.studies.pareto")}),
    ("sicomat.plots.study", "def plot():\n    from ..studies.pareto import pareto_front\n",
     {("sicomat.plots.study", "sicomat.studies.pareto")}),
])
def test_the_checker_catches_a_planted_violation(module, text, expected):
    found = violations(imports_of(text, module, False, _KNOWN))
    assert set(found) == expected


def test_the_cycle_finder_finds_a_planted_cycle():
    imports = imports_of("def f():\n    from ..servo import loop\n", "sicomat.mechanics.lumped", False, _KNOWN) + \
        imports_of("from ..mechanics.lumped import Mechanics\n", "sicomat.servo.loop", False, _KNOWN) + \
        imports_of("class R:\n    def plot(self):\n        from ..plots import base\n", "sicomat.lti.plant",
                   False, _KNOWN) + \
        imports_of("from ..lti.plant import Plant\n", "sicomat.plots.base", False, _KNOWN)
    # the lumped ⇄ loop knot is found; the lti.plant → plots.base → lti.plant loop through .plot() is not
    assert cycles(runtime_graph(imports)) == [["sicomat.mechanics.lumped", "sicomat.servo.loop"]]


# --------------------------------------------------------------------------- module size
MAX_LINES = 400
# Modules over MAX_LINES lines, each on one topic (say which). A new long module fails the test
# until it is split or listed here with its reason; a listed one that got short must leave the list.
LONG_MODULES: dict[str, str] = {
    "sicomat.lti.response": "the one frequency-response evaluator (strategies, accuracy contract) and its result",
    "sicomat.simulation.kernel": "the compiled (numba) kernel that executes a hybrid program, single and batched",
    "sicomat.simulation.nonlinear": "the compiled large-motion engine of a robot machine: its loop, right-hand side and stick-slip",
    "sicomat.simulation.envelope": "bounds of the friction-event functions inside a base step (in-step events)",
    "sicomat.reduction.balanced": "Gramian-based reduction: balanced truncation and its variants (Schur, frequency-limited, Hankel norm)",
    "sicomat.reduction.physical": "physical regrouping: a smaller lumped model that keeps named bodies",
    "sicomat.reduction.error": "what a reduction cost (frequency errors on a pole-aware grid) and its result",
    "sicomat.frequency.margins": "stability margins of a loop gain on a grid (all crossovers) and the bandwidth",
    "sicomat.tuning.frequency": "the frequency approach of the tuning (rigid closed form, then the complete model)",
    "sicomat.servo.loop": "the servo loop: resolved from the axis description and lowered to a hybrid program",
    "sicomat.cli.main": "the CLI's commands, each delegating to the library",
    "sicomat.io.modelfile": "the model file in and out: reading with its limits, --set key paths, validation messages, saving",
    "sicomat.description.chain": "the lowering of a drive chain of parts to lumped bodies and springs (one walk, then the detail)",
}


def test_long_modules_are_listed_with_their_topic():
    sizes = {name: len(path.read_text(encoding="utf-8").splitlines()) for name, path in all_modules().items()}
    unlisted = {name: n for name, n in sizes.items() if n > MAX_LINES and name not in LONG_MODULES}
    short = {name for name in LONG_MODULES if sizes.get(name, 0) <= MAX_LINES}
    assert not unlisted, (f"modules over {MAX_LINES} lines: split them or list them in LONG_MODULES with their "
                          f"one topic: {unlisted}")
    assert not short, f"at or under {MAX_LINES} lines (or gone) now, remove from LONG_MODULES: {sorted(short)}"


# --------------------------------------------------------------------------- the public names
def test_every_top_level_name_resolves():
    """``sicomat/__init__`` exports the pipeline's names lazily: each one must import."""
    import sicomat

    missing = {}
    for name in sicomat.__all__:
        try:
            getattr(sicomat, name)
        except AttributeError as exc:
            missing[name] = str(exc)
    assert not missing, missing


# --------------------------------------------------------------------------- static types
def test_mypy_clean(tmp_path):
    """``mypy`` (configured in pyproject.toml, [tool.mypy]; a test dependency, so a missing mypy fails
    here rather than skipping) finds no error in src/sicomat."""
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    run = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
                          "--cache-dir", str(tmp_path / "mypy-cache"), str(PACKAGE)],
                         cwd=ROOT, capture_output=True, text=True, env=env)
    assert run.returncode == 0, f"mypy failed (exit {run.returncode}):\n{run.stdout}\n{run.stderr}"
