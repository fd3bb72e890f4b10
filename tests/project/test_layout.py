"""The package layout tells the data flow: no import cycles, and no arrow against the flow; and
the tests mirror the package.

Every module under ``mjxskill/`` is parsed with ``ast``; every import counts, function-local
ones included (a lazy import is still a dependency). ``from pkg import name`` is an edge to the
module ``pkg.name`` when that is a module, else to ``pkg``. See docs/architecture.md for the map
these rules keep true.
"""

from __future__ import annotations

import ast
import io
import os
import subprocess
import sys
import tokenize
from functools import lru_cache
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "mjxskill"
TESTS = PACKAGE.parent / "tests"
# the folders of tests/ that mirror no package: the benchmark scripts' tests, the checks of the
# repository as a whole, and what the tests share (modules on sys.path, tests/conftest.py)
OWN_TEST_FOLDERS = ("benchmarks", "project", "helpers")
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


CORE = ("scenario", "planner", "ebt", "task", "bt_compiled", "sim", "engine", "gp", "errors", "_runtime", "_lazy", "_headless")
# the applications over the core, each only importing those before it: the run directory, the
# twin calibrated from recordings, the optimizer loop, what follows training, the experiment and
# the explore page, the command line
APPLICATIONS = ("runs", "calibration", "training", "evaluation", "experiment", "explore", "cli")
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
        if in_stage(m, ("engine.native", "engine.native_reference")):
            reached = closure(m) | {m}
            assert not any(in_stage(r, ("engine.mjx",)) for r in reached), (m, sorted(r for r in reached if in_stage(r, ("engine.mjx",))))
            assert not any("mujoco.mjx" in graph()[r] for r in reached), m
            mjx_from = [r for r in reached if "mjx" in {a.name for a in _mjx_aliases(r)}]
            assert mjx_from == [], (m, mjx_from)


def test_the_native_references_serve_the_tests_and_benchmarks_only():
    # engine/native/ is the production engine; what it is checked against (the plain loop over a
    # call, the numpy lockstep law) is engine/native_reference.py, which no module of the package imports
    assert "mjxskill.engine.native_reference" in modules()
    assert [m for m in modules() if "mjxskill.engine.native_reference" in internal(m)] == []


def test_parallelism_wraps_the_one_process_native_engine():
    # worker processes and Ray are wrappers around NativeRollout (pool, ray_pool), which imports neither
    assert closure("mjxskill.engine.native.rollout") & {"mjxskill.engine.native.pool", "mjxskill.engine.native.ray_pool"} == set()
    assert "ray" not in graph()["mjxskill.engine.native.rollout"]


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


def test_the_tests_mirror_the_package():
    """tests/<package>/ holds the tests of mjxskill/<package>/ (tests/engine/mjx/ those of
    mjxskill/engine/mjx/); the only other folders of Python files are tests/'s own, one level deep."""
    folders = {p.parent.relative_to(TESTS) for p in TESTS.rglob("*.py")} - {Path(".")}
    mirrored = [f for f in folders if f.parts[0] not in OWN_TEST_FOLDERS]
    assert mirrored and [str(f) for f in mirrored if not (PACKAGE / f / "__init__.py").is_file()] == []
    assert sorted(str(f) for f in folders if f.parts[0] in OWN_TEST_FOLDERS) == sorted(OWN_TEST_FOLDERS)


def test_every_test_is_collected_and_no_test_module_imports_another():
    """A test function outside a ``test_*.py`` file is never run (pytest collects only those), and
    a test module imported by another is found only where its folder happens to be on sys.path:
    what tests share is a module of tests/helpers/ or a fixture of a conftest.py."""
    stray, imported = [], []
    for path in sorted(TESTS.rglob("*.py")):
        where = str(path.relative_to(TESTS))
        tree = ast.parse(path.read_text(), where)
        if not path.name.startswith("test_"):
            stray += [f"{where}: {n.name}" for n in tree.body
                      if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and n.name.lower().startswith("test")]
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            imported += [f"{where}:{node.lineno}: {name}" for name in names
                         if name.split(".")[-1].startswith(("test_", "conftest"))]
    assert (stray, imported) == ([], [])


@pytest.mark.parametrize("module", sorted(modules()))
def test_modules_stay_small(module):
    path = modules()[module]
    lines = len(path.read_text().splitlines())
    if lines <= MAX_LINES:
        return
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    assert "longer than" in doc.lower(), f"{path.relative_to(PACKAGE.parent)} has {lines} lines and no docstring saying why"


MAX_FUNCTION_LINES = 80


@pytest.mark.parametrize("module", sorted(modules()))
def test_functions_stay_short(module):
    path = modules()[module]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            lines = node.end_lineno - node.lineno + 1
            if lines > MAX_FUNCTION_LINES:
                doc = ast.get_docstring(node) or ""
                assert "longer than" in doc.lower(), (
                    f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {node.name} has {lines} lines and no docstring saying why")


# modules whose local imports are being moved or commented (none now)
NOT_YET_CHECKED: set[str] = set()


def _not_yet_checked(module: str) -> bool:
    return any(module == m or module.startswith(m + ".") for m in NOT_YET_CHECKED)


def _local_imports(tree: ast.AST) -> list[ast.stmt]:
    """Import statements inside a function body (nested ones included), in source order."""
    found = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            if in_function and isinstance(child, (ast.Import, ast.ImportFrom)):
                found.append(child)
            visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    visit(tree, False)
    return sorted(found, key=lambda n: n.lineno)


def _comment_lines(source: str) -> tuple[set[int], set[int]]:
    """(lines holding a comment, lines holding only a comment)."""
    any_comment, only_comment = set(), set()
    code_lines = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            any_comment.add(tok.start[0])
        elif tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENDMARKER):
            code_lines.update(range(tok.start[0], tok.end[0] + 1))
    only_comment = any_comment - code_lines
    return any_comment, only_comment


def uncommented_local_imports(source: str, label: str) -> list[str]:
    """Function-local imports of ``source`` (``label``: its file) with no comment saying why they are not at the top:
    a comment on the import's own line(s), or a comment line just above it. An import right
    below a commented local import shares its comment (a block of lazy imports, one reason)."""
    any_comment, only_comment = _comment_lines(source)
    explained: set[int] = set()  # last lines of local imports that have their reason
    bad = []
    for node in _local_imports(ast.parse(source, label)):
        own = any(line in any_comment for line in range(node.lineno, node.end_lineno + 1))
        above = node.lineno - 1
        if own or above in only_comment or above in explained:
            explained.add(node.end_lineno)
        else:
            bad.append(f"{label}:{node.lineno}: {ast.get_source_segment(source, node)}")
    return bad


def test_the_comment_rule_sees_what_it_should():
    sample = (
        "import os\n"
        "def f():\n"
        "    import a  # lazy: why\n"
        "    import b\n"
        "def g():\n"
        "    # lazy: why\n"
        "    import c\n"
        "def h():\n"
        "    x = 1\n"
        "    import d\n"
        "    class K:\n"
        "        def m(self):\n"
        "            s = '#'; import e\n"
    )
    assert uncommented_local_imports(sample, "sample.py") == ["sample.py:10: import d", "sample.py:13: import e"]


def test_every_function_local_import_says_why_it_is_local():
    """Imports sit at the top of their module; one inside a function keeps a comment saying
    why (start-up cost on a measured path, an order that matters, the engine not run)."""
    bad = []
    for name, path in modules().items():
        if not _not_yet_checked(name):
            bad += uncommented_local_imports(path.read_text(), str(path.relative_to(PACKAGE.parent)))
    assert bad == [], "function-local imports without a comment saying why:\n" + "\n".join(bad)


# Imports sit at the top of their module; a function-local one is kept only where importing it
# at the top would make a light command (plan, select, --help, bad input) import jax, mujoco,
# torch, optuna, ray or matplotlib, or an order or cycle requires it
MAX_LOCAL_IMPORTS = 30


def test_few_imports_are_function_local():
    found = [f"{path.relative_to(PACKAGE.parent)}:{node.lineno}" for path in modules().values()
             for node in _local_imports(ast.parse(path.read_text(), str(path)))]
    assert len(found) <= MAX_LOCAL_IMPORTS, "\n".join(found)


def test_not_yet_checked_names_modules_that_exist():
    for name in NOT_YET_CHECKED:
        assert name in modules(), name


def _python(code: str, env: dict | None = None) -> str:
    """The last line ``code`` prints, run in a fresh interpreter (what a command starts with)."""
    done = subprocess.run([sys.executable, "-c", code], cwd=PACKAGE.parent, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip().splitlines()[-1]


def test_plan_starts_no_jax():
    """``python -m mjxskill.plan push`` plans without importing jax (the lazy imports above keep it so)."""
    code = (
        "import runpy, sys\n"
        "sys.argv = ['mjxskill.plan', 'push']\n"
        "try:\n"
        "    runpy.run_module('mjxskill.plan', run_name='__main__')\n"
        "except SystemExit as stop:\n"
        "    assert stop.code == 0, stop.code\n"
        "print(sorted(m for m in sys.modules if m == 'jax' or m.startswith('jax.')))\n"
    )
    assert _python(code) == "[]"


def test_the_rendering_commands_choose_the_gl_backend_before_mujoco_is_imported():
    """mujoco reads MUJOCO_GL once, when imported: select and explore import it only after
    ``default_gl()`` (headless: egl), even though building select's parser imports it."""
    code = (
        "import os, sys\n"
        "seen = []\n"
        "class Spy:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'mujoco' and not seen:\n"
        "            seen.append(os.environ.get('MUJOCO_GL'))\n"
        "sys.meta_path.insert(0, Spy())\n"
        "import mjxskill.cli.explore, mjxskill.cli.select\n"
        "assert not seen, 'importing the commands imported mujoco'\n"
        "assert mjxskill.cli.select.main(['/nonexistent']) == 2\n"
        "print(seen)\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MUJOCO_GL")}
    assert _python(code, env) == "['egl']"
