"""The package layout tells the data flow: no import cycles, and no arrow against the flow.

Every module under ``mjxskill/`` is parsed with ``ast``; every import counts, function-local
ones included (a lazy import is still a dependency). ``from pkg import name`` is an edge to the
module ``pkg.name`` when that is a module, else to ``pkg``. See docs/architecture.md for the map
these rules keep true.
"""

from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mjxskill"
MAX_LINES = 400


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@lru_cache(maxsize=1)
def modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path) -> set[str]:
    """Dotted names this module imports (mjxskill modules resolved, others as written)."""
    mods = modules()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(parts + ([base] if base else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.add(sub if sub in mods or not base.startswith("mjxskill") else base)
    return found


@lru_cache(maxsize=1)
def graph() -> dict[str, set[str]]:
    """module -> imported names (internal edges resolved to modules)."""
    mods = modules()
    result = {}
    for name, path in mods.items():
        edges = set()
        for target in _imports(name, path):
            if target.startswith("mjxskill"):
                while target not in mods and "." in target:  # `import mjxskill.a.b` names a module
                    target = target.rpartition(".")[0]
            if target != name:
                edges.add(target)
        result[name] = edges
    return result


def internal(name: str) -> set[str]:
    return {t for t in graph()[name] if t in modules()}


def closure(name: str) -> set[str]:
    """Every mjxskill module ``name`` imports, directly or not (itself excluded)."""
    seen, stack = set(), [name]
    while stack:
        for t in internal(stack.pop()):
            if t not in seen:
                seen.add(t)
                stack.append(t)
    seen.discard(name)
    return seen


def test_the_parser_sees_the_modules_and_their_local_imports():
    mods = modules()
    assert "mjxskill.engine.mjx.compiled" in mods and "mjxskill.cli.train" in mods
    # compile_rollout plans inside a function body: a local import is an edge too
    assert "mjxskill.task" in graph()["mjxskill.engine.mjx.compiled"]
    assert "mujoco.mjx" in graph()["mjxskill.engine.mjx.episode"] or "mujoco" in graph()["mjxskill.engine.mjx.episode"]


def test_no_import_cycles():
    index, low, on_stack, stack, cycles = {}, {}, set(), [], []
    counter = [0]

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in internal(v):
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
                cycles.append(sorted(component))

    for v in modules():
        if v not in index:
            visit(v)
    assert cycles == []


CORE = ("scenario", "planner", "ebt", "task", "bt_compiled", "sim", "engine", "gp", "errors", "_runtime")
# the applications over the core, each only importing those before it: the run directory, the
# optimizer loop, what follows training, the experiment and the explore page, the command line
APPLICATIONS = ("runs", "training", "evaluation", "experiment", "explore", "cli")
ROBOT = ("scenario", "planner", "ebt", "task", "bt_compiled", "sim", "engine", *APPLICATIONS)


def stage(module: str) -> str:
    """The pipeline stage of a module: its first-level package or module under mjxskill, and
    the engine package's subpackage (``engine.mjx``). A package's ``__main__`` (``python -m``)
    is the command line's."""
    parts = module.split(".")
    if parts[-1] == "__main__":
        return "cli"
    if len(parts) > 2 and parts[1] == "engine":
        return f"engine.{parts[2]}"
    return parts[1] if len(parts) > 1 else ""


def in_stage(module: str, stages) -> bool:
    s = stage(module)
    return s in stages or s.partition(".")[0] in stages


def arrows(sources, targets) -> list[str]:
    return sorted(
        f"{m} -> {t}"
        for m in modules()
        if in_stage(m, sources)
        for t in internal(m)
        if in_stage(t, targets)
    )


def test_core_stages_never_import_the_applications():
    assert arrows(CORE, APPLICATIONS) == []


@pytest.mark.parametrize("k", range(len(APPLICATIONS) - 1))
def test_each_application_imports_only_those_before_it(k):
    assert arrows((APPLICATIONS[k],), APPLICATIONS[k + 1:]) == []


def test_the_optimizer_knows_no_robot():
    assert arrows(("gp",), ROBOT) == []


def test_the_native_engine_is_independent_of_the_compiled_one():
    # directly or through another module: the fidelity reference must not run what it checks
    for m in modules():
        if in_stage(m, ("engine.native",)):
            reached = closure(m) | {m}
            assert not any(in_stage(r, ("engine.mjx",)) for r in reached), (m, sorted(r for r in reached if in_stage(r, ("engine.mjx",))))
            assert not any("mujoco.mjx" in graph()[r] for r in reached), m
            mjx_from = [r for r in reached if "mjx" in {a.name for a in _mjx_aliases(r)}]
            assert mjx_from == [], (m, mjx_from)


def test_the_shared_engine_modules_and_the_simulated_model_import_no_engine():
    assert arrows(("engine.common", "sim"), ("engine.mjx", "engine.native", "engine.build")) == []


def _mjx_aliases(module: str):
    """``from mujoco import mjx`` in ``module``."""
    tree = ast.parse(modules()[module].read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "mujoco":
            yield from node.names


def test_the_planner_runs_without_jax():
    for m in modules():
        if in_stage(m, ("planner",)):
            for r in closure(m) | {m}:
                assert not any(t == "jax" or t.startswith("jax.") for t in graph()[r]), (m, r)


def test_shared_engine_modules_import_no_mjx():
    shared = [m for m in modules() if in_stage(m, ("engine.common",))]
    assert "mjxskill.engine.common.types" in shared
    for m in shared:
        assert not any(True for _ in _mjx_aliases(m)) and "mujoco.mjx" not in graph()[m], m


@pytest.mark.parametrize("module", sorted(modules()))
def test_modules_stay_small(module):
    path = modules()[module]
    lines = len(path.read_text().splitlines())
    if lines <= MAX_LINES:
        return
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    assert "longer than" in doc.lower(), f"{path.relative_to(PACKAGE.parent)} has {lines} lines and no docstring saying why"
